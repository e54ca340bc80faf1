// The crease rule's default angle on a real CAD export: OpenCASCADE's
// Pump_Nut.brep tessellated as data/cad/pump_nut_coarse.stl (facet normals
// only). Its two flat end faces meet a 30-degree chamfer whose facets the
// mesher leaves 29 to 30 degrees from them; a crease angle at 30 degrees
// averaged some of those corners with the chamfer and not others, which the
// full render showed as radial streaks on a flat face.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/math.h"
#include "geometry/crease_normals.h"
#include "render/embree_scene.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

struct EndFaceCorners {
  size_t triangles = 0;  // triangles of the end faces
  size_t bent = 0;       // their corners more than 2 degrees off the face's normal
  double worst_deg = 0;  // the largest angle between such a corner and its face
};

// The end faces' normals are +Y and -Y (the nut's axis).
EndFaceCorners end_face_corners(const TriangleMesh& m) {
  EndFaceCorners out;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const Vec3d a(m.positions[m.indices[3 * t]]), b(m.positions[m.indices[3 * t + 1]]),
        c(m.positions[m.indices[3 * t + 2]]);
    const Vec3d n = face_normal(a, b, c);
    if (n == Vec3d(0)) continue;  // degenerate
    if (std::abs(n.y) < 1 - 1e-6) continue;
    ++out.triangles;
    for (int k = 0; k < 3; ++k) {
      const Vec3d cn(m.normals[m.indices[3 * t + size_t(k)]]);
      const double deg = std::acos(std::clamp(glm::dot(cn, n), -1.0, 1.0)) * 180.0 / M_PI;
      if (deg > 2.0) ++out.bent;
      out.worst_deg = std::max(out.worst_deg, deg);
    }
  }
  return out;
}

TEST(CadCreases, TheNutsEndFacesShadeFlatAtTheDefaultAngle) {
  const fs::path stl = fs::path(RAYLOD_DATA_DIR) / "cad" / "pump_nut_coarse.stl";
  auto mesh = load_triangle_mesh(stl, glm::dmat4(1.0), 0, kDefaultCreaseAngleDeg);
  ASSERT_TRUE(mesh.is_ok()) << mesh.status().message();
  ASSERT_EQ(mesh->triangle_count(), 9396u);
  ASSERT_EQ(mesh->normals.size(), mesh->positions.size());
  const EndFaceCorners d = end_face_corners(*mesh);
  EXPECT_EQ(d.triangles, 368u);
  // Within a degree: where an end face runs tangentially into a round (its
  // first facets 1.9 degrees off the face), its corners lean by less.
  EXPECT_EQ(d.bent, 0u) << "worst " << d.worst_deg << " degrees";
  EXPECT_LT(d.worst_deg, 1.0);
  // The file does have the borderline dihedrals: at 31 degrees some end-face
  // corners are averaged with the chamfer (so this test sees the streaks).
  auto at31 = load_triangle_mesh(stl, glm::dmat4(1.0), 0, 31.0);
  ASSERT_TRUE(at31.is_ok()) << at31.status().message();
  const EndFaceCorners d31 = end_face_corners(*at31);
  EXPECT_GT(d31.bent, 0u);
  EXPECT_GT(d31.worst_deg, 10.0);
  std::printf("end-face corners: %zu of %zu triangles' bent at 31 degrees (worst %.2f), worst %.2f at the default\n",
              d31.bent, d31.triangles, d31.worst_deg, d.worst_deg);
}

}  // namespace
}  // namespace raylod
