// Unseen cells and the shadows they cast (probe.h, "Unseen cells"), on a
// real CAD export in a close-up lit by a key and a fill light
// (data/cad/crankarm_coarse.stl, data/cad/crankarm_closeup.json): the
// shadows of the parts the camera cannot see fall into the view's frustum
// almost everywhere, but onto what the camera sees only near it. Cells
// whose shadows fall on nothing seen collapse (ProbeConfig::
// shadow_receivers): fewer triangles than by the frustum alone, the cut
// no finer anywhere, and the image still at or above the noise floor.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "pipeline/noise_floor.h"
#include "pipeline/noise_floor_check.h"
#include "pipeline/pipeline.h"
#include "probe/probe.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

TEST(CadShadowReceivers, UnseenCellsWhoseShadowsFallOnNothingSeenCollapse) {
  test::ScratchDir scratch("cad-shadow-receivers");
  const fs::path data = fs::path(RAYLOD_DATA_DIR) / "cad";
  const fs::path mesh = scratch.path / "crankarm_coarse.stl";
  fs::copy_file(data / "crankarm_coarse.stl", mesh, fs::copy_options::overwrite_existing);
  auto loaded = load_scene(data / "crankarm_closeup.json");
  ASSERT_TRUE(loaded.is_ok()) << loaded.status().message();
  const Scene& scene = *loaded;
  ASSERT_EQ(scene.lights.size(), 2u);

  auto run = [&](bool receivers) {
    RunOptions o;
    o.mesh_override = mesh;
    o.cache_dir = scratch.path / "cache";
    o.use_cache = false;
    o.progress = false;
    o.shadow_receivers = receivers;
    return run_pipeline(scene, o, nullptr);
  };
  auto with = run(true), without = run(false);
  ASSERT_TRUE(with.is_ok()) << with.status().message();
  ASSERT_TRUE(without.is_ok()) << without.status().message();
  ASSERT_EQ(with->cuts.size(), 1u);
  EXPECT_LT(with->triangles_out * 5, without->triangles_out * 4) << "at least a fifth fewer triangles";
  // Every cell of the cut by the frustum lies in a cell of the cut by the
  // receivers: they only let cells collapse further.
  std::set<CellKey> cells;
  for (const CollapsedCell& c : with->cuts[0].cells) cells.insert(c.key);
  for (const CollapsedCell& c : without->cuts[0].cells) {
    bool inside = false;
    for (CellKey k = c.key;; k = k.parent()) {
      if (cells.count(k)) { inside = true; break; }
      if (k.level == 0) break;
    }
    EXPECT_TRUE(inside) << "cell " << c.key.level << ":" << c.key.code;
  }

  RenderOptions ro;
  ro.progress = false;
  ro.mesh_override = {mesh};
  auto full = render_full_with_noise_floor(scene, ro);
  ASSERT_TRUE(full.is_ok()) << full.status().message();
  test::expect_within_noise_floor(with->render.color, *full);
}

}  // namespace
}  // namespace raylod
