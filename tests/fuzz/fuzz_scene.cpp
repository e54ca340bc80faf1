// libFuzzer target: the scene parser (parse_scene on the input as JSON text).
// Mesh paths resolve against a folder that does not exist, so a parsed scene
// names only absolute paths that exist; nothing is opened but checked.
#include <string>

#include "fuzz_input.h"
#include "scene/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto scene = raylod::parse_scene(text, "/nonexistent/raylod-fuzz", "fuzz.json");
  if (!scene) {
    RAYLOD_FUZZ_CHECK(!scene.status().message().empty());
    return 0;
  }
  // What the parser promises the renderer about a scene it accepts.
  const raylod::Scene& s = *scene;
  RAYLOD_FUZZ_CHECK(s.camera.width > 0 && s.camera.height > 0);
  RAYLOD_FUZZ_CHECK(s.camera.fov_y_deg > 0 && s.camera.fov_y_deg < 180);
  RAYLOD_FUZZ_CHECK(!s.materials.empty() && !s.objects.empty());
  for (const raylod::SceneObject& o : s.objects) {
    RAYLOD_FUZZ_CHECK(o.material >= 0 && size_t(o.material) < s.materials.size());
    RAYLOD_FUZZ_CHECK(o.generate.has_value() == o.mesh.empty());
  }
  if (s.ground) RAYLOD_FUZZ_CHECK(s.ground->material >= 0 && size_t(s.ground->material) < s.materials.size());
  RAYLOD_FUZZ_CHECK(s.spp >= 1);
  return 0;
}
