// The pipeline on a real CAD export (data/cad/crankarm_coarse.stl: facet
// normals only, creases everywhere) with nothing collapsed: the simplified
// mesh is then the input, Draco-quantised and shaded by the same crease rule
// as the full render, so its render must be as close to the full render as
// another seed of the full render is (the noise floor), or closer.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "pipeline/image_compare.h"
#include "pipeline/noise_floor.h"
#include "pipeline/noise_floor_check.h"
#include "pipeline/pipeline.h"
#include "render/embree_scene.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// The part's scene at a small size. The store is built beside its mesh, so
// the mesh is copied into the scratch directory rather than used in data/.
Scene small_cad_scene(const fs::path& scratch, fs::path& mesh) {
  const fs::path data = fs::path(RAYLOD_DATA_DIR) / "cad";
  mesh = scratch / "crankarm_coarse.stl";
  fs::copy_file(data / "crankarm_coarse.stl", mesh, fs::copy_options::overwrite_existing);
  auto scene = load_scene(data / "crankarm_coarse.json");
  EXPECT_TRUE(scene.is_ok()) << scene.status().message();
  Scene s = *scene;
  s.camera.width = 240;
  s.camera.height = 180;
  s.spp = 4;
  return s;
}

TEST(CadNoiseFloor, NothingCollapsedIsWithinTheNoiseFloor) {
  test::ScratchDir scratch("cad-noise-floor");
  fs::path mesh;
  const Scene scene = small_cad_scene(scratch.path, mesh);

  RunOptions run;
  run.mesh_override = mesh;
  run.cache_dir = scratch.path / "cache";
  run.use_cache = false;
  run.progress = false;
  run.rays = 2000;
  // No cell is smaller than a millionth of a footprint: nothing collapses.
  run.footprint_scale = 1e-6;
  auto r = run_pipeline(scene, run, nullptr);
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  ASSERT_EQ(r->cuts.size(), 1u);
  EXPECT_TRUE(r->cuts[0].cells.empty()) << r->cuts[0].cells.size() << " cells collapsed";
  EXPECT_EQ(r->triangles_in, 8244u);
  // Every triangle is kept but those with a repeated corner, which the file
  // has (OCCT's mesher leaves a few) and which cover no pixel.
  auto input = load_triangle_mesh(mesh, glm::dmat4(1.0), 0, scene.crease_angle_deg);
  ASSERT_TRUE(input.is_ok()) << input.status().message();
  uint64_t degenerate = 0;
  for (size_t t = 0; t < input->triangle_count(); ++t) {
    const Vec3 a = input->positions[input->indices[3 * t]], b = input->positions[input->indices[3 * t + 1]],
               c = input->positions[input->indices[3 * t + 2]];
    degenerate += a == b || b == c || a == c;
  }
  EXPECT_EQ(r->triangles_out, r->triangles_in - degenerate) << degenerate << " degenerate input triangles";

  RenderOptions ro;
  ro.progress = false;
  ro.mesh_override = {mesh};
  auto full = render_full_with_noise_floor(scene, ro);
  ASSERT_TRUE(full.is_ok()) << full.status().message();
  const NoiseFloor& floor = full->noise_floor;
  EXPECT_EQ(floor.seed, scene.seed);
  EXPECT_EQ(floor.spp, 4);
  // Antialiased edges at 4 spp: two seeds differ, but not by much.
  ASSERT_TRUE(std::isfinite(floor.psnr()));
  EXPECT_GT(floor.psnr(), 25.0);

  test::expect_within_noise_floor(r->render.color, *full);

  // The floor does tell a wrong shading rule from sampling noise: the full
  // mesh smoothed across its creases (crease angle 180) is below it. (Flat
  // facets, crease angle 0, are not: on this 10-degree tessellation they
  // change few pixels by little, less than the noise along the silhouettes.)
  Scene smoothed = scene;
  smoothed.crease_angle_deg = 180;
  auto smooth = render(smoothed, ro);
  ASSERT_TRUE(smooth.is_ok()) << smooth.status().message();
  auto es = compare_images(smooth->color, full->reference.color);
  ASSERT_TRUE(es.is_ok());
  EXPECT_FALSE(within_noise_floor(*es, floor)) << "smoothed PSNR " << es->psnr << " dB, floor " << floor.psnr();
}

}  // namespace
}  // namespace raylod
