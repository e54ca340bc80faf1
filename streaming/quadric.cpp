// Plane quadrics (Garland and Heckbert, SIGGRAPH 1997; Lindstrom, SIGGRAPH
// 2000; METHOD.md eq. 4). For the plane p = [n, d] with unit normal n through
// x (d = -n.x), Q = p p^T = [[n n^T, n d], [d n^T, d^2]], stored with the
// eq. 4 sign convention Q = [[A, -b], [-b^T, c]]: A = n n^T, b = n (n.x),
// c = (n.x)^2. Callers pass x relative to a local origin so that c and b stay
// small for CAD coordinates far from zero.
#include "streaming/octree_store.h"

namespace raylod {

Quadric quadric_from_plane(const Vec3d& n, const Vec3d& x, double weight) {
  const double nx = glm::dot(n, x);
  Quadric q;
  q.a00 = weight * n.x * n.x;
  q.a01 = weight * n.x * n.y;
  q.a02 = weight * n.x * n.z;
  q.a11 = weight * n.y * n.y;
  q.a12 = weight * n.y * n.z;
  q.a22 = weight * n.z * n.z;
  q.b0 = weight * n.x * nx;
  q.b1 = weight * n.y * nx;
  q.b2 = weight * n.z * nx;
  q.c = weight * nx * nx;
  return q;
}

void quadric_add(Quadric& q, const Quadric& r) {
  q.a00 += r.a00; q.a01 += r.a01; q.a02 += r.a02;
  q.a11 += r.a11; q.a12 += r.a12; q.a22 += r.a22;
  q.b0 += r.b0; q.b1 += r.b1; q.b2 += r.b2;
  q.c += r.c;
}

double quadric_error(const Quadric& q, const Vec3d& v) {
  // v^T A v with A symmetric.
  const double vav = q.a00 * v.x * v.x + q.a11 * v.y * v.y + q.a22 * v.z * v.z +
                     2 * (q.a01 * v.x * v.y + q.a02 * v.x * v.z + q.a12 * v.y * v.z);
  const double bv = q.b0 * v.x + q.b1 * v.y + q.b2 * v.z;
  return vav - 2 * bv + q.c;
}

}  // namespace raylod
