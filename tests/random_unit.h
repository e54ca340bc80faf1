// A seeded, uniformly distributed unit vector for property tests.
#pragma once

#include <random>

#include "core/math.h"

namespace raylod::test {

inline Vec3d random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  for (;;) {
    const Vec3d v(g(rng), g(rng), g(rng));
    const double l = glm::length(v);
    if (l > 1e-6) return v / l;
  }
}

}  // namespace raylod::test
