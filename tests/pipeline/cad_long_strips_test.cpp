// The pipeline at its defaults on a real CAD export whose curved wall is
// tessellated as long strips (data/cad/occ_bottle_coarse.stl, OpenCASCADE's
// bottle: each strip one triangle pair from the rounded base to the
// shoulder), in a close-up of the wall (data/cad/occ_bottle_closeup.json):
// every strip seen ends in cells off the view, which the unreached-cell
// policy collapses coarsely. Collapsed, a strip's far corner took the mean
// normal of a cell that also holds the base's round, and the whole visible
// strip was shaded by that tilt (3.4 dB below the noise floor). The cut now
// bounds the normal at the far ends of the triangles its rays hit
// (probe.h): the close-up must stay at or above the floor, still
// simplified.
#include <gtest/gtest.h>

#include <filesystem>

#include "pipeline/noise_floor.h"
#include "pipeline/noise_floor_check.h"
#include "pipeline/pipeline.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

TEST(CadLongStrips, TheBottlesCloseUpIsWithinTheNoiseFloorAtTheDefaults) {
  test::ScratchDir scratch("cad-long-strips");
  const fs::path data = fs::path(RAYLOD_DATA_DIR) / "cad";
  // The store is built beside its mesh: a copy in the scratch directory.
  const fs::path mesh = scratch.path / "occ_bottle_coarse.stl";
  fs::copy_file(data / "occ_bottle_coarse.stl", mesh, fs::copy_options::overwrite_existing);
  auto loaded = load_scene(data / "occ_bottle_closeup.json");
  ASSERT_TRUE(loaded.is_ok()) << loaded.status().message();
  const Scene& scene = *loaded;

  RunOptions run;
  run.mesh_override = mesh;
  run.cache_dir = scratch.path / "cache";
  run.use_cache = false;
  run.progress = false;
  auto r = run_pipeline(scene, run, nullptr);
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  ASSERT_EQ(r->cuts.size(), 1u);
  EXPECT_EQ(r->triangles_in, 19418u);
  EXPECT_LT(r->triangles_out * 3, r->triangles_in) << "the close-up must still simplify";
  EXPECT_GT(r->cuts[0].counters.at("cells_kept_for_far_normal"), 0u);

  RenderOptions ro;
  ro.progress = false;
  ro.mesh_override = {mesh};
  auto full = render_full_with_noise_floor(scene, ro);
  ASSERT_TRUE(full.is_ok()) << full.status().message();
  test::expect_within_noise_floor(r->render.color, *full);
}

}  // namespace
}  // namespace raylod
