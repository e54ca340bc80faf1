// Which meshes get their folds refined: only those a mirror or glass object
// uses (simulate only what the scene calls for; opaque shading is two-sided).
#include <gtest/gtest.h>

#include "pipeline/pipeline.h"

namespace raylod {
namespace {

TEST(FoldPasses, OnlyForStoresAMirrorOrGlassObjectUses) {
  Scene scene;
  Material diffuse, glass, mirror, black_mirror;
  diffuse.type = MaterialType::Diffuse;
  glass.type = MaterialType::Glass;
  mirror.type = MaterialType::Mirror;
  mirror.reflectance = 0.8f;
  black_mirror.type = MaterialType::Mirror;
  black_mirror.reflectance = 0.0f;  // reflects nothing: opaque for this purpose
  scene.materials = {diffuse, glass, mirror, black_mirror};
  // Store 0: diffuse only; store 1: diffuse and glass instances; store 2: mirror; store 3: black mirror.
  const std::vector<ProbeObject> objects = {{0, glm::dmat4(1.0), 0}, {1, glm::dmat4(1.0), 0},
                                            {1, glm::dmat4(1.0), 1}, {2, glm::dmat4(1.0), 2},
                                            {3, glm::dmat4(1.0), 3}};
  EXPECT_EQ(fold_passes_for(scene, objects, 0), 0);
  EXPECT_EQ(fold_passes_for(scene, objects, 1), kSpecularFoldPasses);
  EXPECT_EQ(fold_passes_for(scene, objects, 2), kSpecularFoldPasses);
  EXPECT_EQ(fold_passes_for(scene, objects, 3), 0);
  EXPECT_EQ(fold_passes_for(scene, objects, 4), 0);  // no object uses it
}

}  // namespace
}  // namespace raylod
