// The uniform baselines of the accuracy report, run on the fully loaded mesh:
// uniform vertex clustering (meshopt_simplifySloppy, the same family as
// raylod's collapse) and quadric edge collapse (meshopt_simplify, the
// strongest in-core simplifier at hand), each driven to a target count.
#pragma once

#include <cstdint>
#include <string>

#include "render/embree_scene.h"

namespace raylod {

enum class Baseline { VertexClustering, EdgeCollapse };
const char* to_string(Baseline b);

struct BaselineResult {
  TriangleMesh mesh;          // simplified, sharing the input's vertex attributes
  double seconds = 0;         // simplifier time only
  uint64_t peak_bytes = 0;    // input arrays + output indices + the simplifier's own peak allocations
};

// Simplifies `input` (welded, indexed) to about target_triangles.
BaselineResult run_baseline(Baseline method, const TriangleMesh& input, uint64_t target_triangles);

}  // namespace raylod
