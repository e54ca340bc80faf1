// Whole-cell visibility tests (probe/cell_visibility.h): tiny exact cases,
// then seeded property tests against brute force (points of the box, of
// its shadow, and the area that faces the eye).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "probe/cell_visibility.h"
#include "random_unit.h"
#include "scene/scene_camera.h"

namespace raylod {
namespace {

Camera camera_at(const Vec3d& eye, const Vec3d& look_at) {
  Camera c;
  c.eye = eye;
  c.look_at = look_at;
  c.up = Vec3d(0, 1, 0);
  c.fov_y_deg = 40;
  c.width = 320;
  c.height = 240;
  return c;
}

std::array<Vec3d, 8> corners(const Bbox& b) {
  std::array<Vec3d, 8> c;
  for (int i = 0; i < 8; ++i)
    c[size_t(i)] = Vec3d(i & 1 ? b.hi.x : b.lo.x, i & 2 ? b.hi.y : b.lo.y, i & 4 ? b.hi.z : b.lo.z);
  return c;
}

// Whether the camera could see point q: in front of the eye and inside the
// image (the pinhole mapping inverted).
bool in_view(const PinholeCamera& cam, const Vec3d& q) {
  const Vec3d s = q - cam.eye;
  const double w = glm::dot(s, cam.forward);
  if (!(w > 0)) return false;
  return std::abs(glm::dot(s, cam.right) / w) <= cam.tan_half_x && std::abs(glm::dot(s, cam.up) / w) <= cam.tan_half_y;
}

Light directional(const Vec3d& d) {
  Light l;
  l.type = LightType::Directional;
  l.direction = glm::normalize(d);
  return l;
}

Light point(const Vec3d& p) {
  Light l;
  l.type = LightType::Point;
  l.position = p;
  return l;
}

TEST(CellVisibility, BoxesAndShadowsBesideTheView) {
  const PinholeCamera cam = make_pinhole_camera(camera_at(Vec3d(0, 0, 10), Vec3d(0, 0, 0)));
  const Frustum f = make_frustum(cam);
  const Bbox ahead{Vec3d(-1), Vec3d(1)};
  const Bbox behind{Vec3d(-1, -1, 12), Vec3d(1, 1, 14)};
  const Bbox left{Vec3d(-40, -1, -1), Vec3d(-38, 1, 1)};
  EXPECT_FALSE(f.outside(corners(ahead)));
  EXPECT_TRUE(f.outside(corners(behind)));
  EXPECT_TRUE(f.outside(corners(left)));
  // Behind the eye, lit along the view: its shadow runs into the view; lit
  // from the front it runs further back.
  EXPECT_FALSE(f.shadow_outside(corners(behind), directional(Vec3d(0, 0, -1))));
  EXPECT_TRUE(f.shadow_outside(corners(behind), directional(Vec3d(0, 0, 1))));
  // Left of the view: a light from the left throws it across the view, one
  // from the right away from it; a point light between it and the view too.
  EXPECT_FALSE(f.shadow_outside(corners(left), directional(Vec3d(1, 0, 0))));
  EXPECT_TRUE(f.shadow_outside(corners(left), directional(Vec3d(-1, 0, 0))));
  EXPECT_TRUE(f.shadow_outside(corners(left), point(Vec3d(-30, 0, 0))));
  EXPECT_FALSE(f.shadow_outside(corners(left), point(Vec3d(-50, 0, 0))));
  // In view, any shadow may be seen.
  EXPECT_FALSE(f.shadow_outside(corners(ahead), directional(Vec3d(0, -1, 0))));
}

// Boxes and lights at random: whenever the tests say outside, no point of
// the box (corners and random points), nor of its shadow (those points
// swept away from the light), projects into the image.
TEST(CellVisibility, WhatIsOutsideIsNotSeen) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1), unit(0, 1);
  int outside = 0, shadow_outside = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Vec3d eye(10 * u(rng), 10 * u(rng), 10 * u(rng));
    const Vec3d centre(20 * u(rng), 20 * u(rng), 20 * u(rng));
    const double half = 0.1 + 3 * unit(rng);
    const Bbox box{centre - Vec3d(half), centre + Vec3d(half)};
    // Every other camera looks near the box.
    const Vec3d look = trial % 2 ? centre + 5 * unit(rng) * test::random_unit(rng) : eye + test::random_unit(rng);
    const PinholeCamera cam = make_pinhole_camera(camera_at(eye, look));
    const Frustum f = make_frustum(cam);
    const std::array<Vec3d, 8> box_corners = corners(box);
    std::vector<Vec3d> points(box_corners.begin(), box_corners.end());
    for (int k = 0; k < 32; ++k) points.push_back(box.lo + Vec3d(unit(rng), unit(rng), unit(rng)) * (box.hi - box.lo));
    if (f.outside(box_corners)) {
      ++outside;
      for (const Vec3d& p : points) EXPECT_FALSE(in_view(cam, p)) << "trial " << trial;
    }
    const Light l = trial % 4 < 2 ? directional(test::random_unit(rng)) : point(Vec3d(20 * u(rng), 20 * u(rng), 20 * u(rng)));
    if (!f.shadow_outside(box_corners, l)) continue;
    ++shadow_outside;
    for (const Vec3d& p : points) {
      const Vec3d away = l.type == LightType::Directional ? l.direction : p - l.position;
      for (double t : {0.0, 0.01, 0.1, 0.5, 1.0, 3.0, 10.0, 100.0, 1e4})
        EXPECT_FALSE(in_view(cam, p + t * away)) << "trial " << trial << " t " << t;
    }
  }
  // Both answers occur.
  EXPECT_GT(outside, 40);
  EXPECT_LT(outside, 360);
  EXPECT_GT(shadow_outside, 20);
}

TEST(CellVisibility, FlatCellsFacingAwayAndTowardsTheEye) {
  const Bbox box{Vec3d(-0.5), Vec3d(0.5)};
  const Vec3d eye(0, 0, 10);  // looking down -z at the box
  const Vec3d away(0, 0, -1);
  EXPECT_TRUE(faces_away(eye, box, away, 1.0, 0.01));
  EXPECT_FALSE(faces_away(eye, box, -away, 1.0, 0.01));
  // Seen edge on, or from inside its bounding ball: not away.
  EXPECT_FALSE(faces_away(eye, box, Vec3d(1, 0, 0), 1.0, 0.01));
  EXPECT_FALSE(faces_away(Vec3d(0, 0, 0.6), box, away, 1.0, 0.01));
  // Normals spread over a hemisphere (R = 0.5): too much may face the eye.
  EXPECT_FALSE(faces_away(eye, box, away, 0.5, 0.01));
  // Tilted until the box's nearest corners see it nearly edge on: a plane
  // whose normal makes angle a with the view direction faces away from
  // every point of the box only while a + beta < 90 degrees.
  const double beta = std::asin(0.5 * std::sqrt(3.0) / 10.0);
  const double a_in = 0.5 * M_PI - 2.1 * beta, a_out = 0.5 * M_PI - 0.9 * beta;
  EXPECT_TRUE(faces_away(eye, box, Vec3d(std::sin(a_in), 0, -std::cos(a_in)), 1.0, 0.01));
  EXPECT_FALSE(faces_away(eye, box, Vec3d(std::sin(a_out), 0, -std::cos(a_out)), 1.0, 0.01));
}

// Cells of random normals (a cluster around a random axis, with weights as
// areas, some stray normals among them): whenever faces_away says so, at
// every sampled point of the box the area whose normal faces that point is
// at most the share given.
TEST(CellVisibility, FacingAwayBoundsTheAreaThatFacesTheEye) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1), unit(0, 1);
  int away = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Vec3d centre(5 * u(rng), 5 * u(rng), 5 * u(rng));
    const double half = 0.05 + unit(rng);
    const Bbox box{centre - Vec3d(half), centre + Vec3d(half)};
    const Vec3d eye = centre + (2 + 20 * unit(rng)) * test::random_unit(rng);
    // Mostly facing away from the eye, so that both answers occur.
    const Vec3d axis = glm::normalize(glm::normalize(centre - eye) + 0.7 * test::random_unit(rng));
    const double spread = 0.5 * unit(rng) * unit(rng);
    const int count = 1 + int(40 * unit(rng));
    std::vector<Vec3d> normals;
    std::vector<double> areas;
    for (int k = 0; k < count; ++k) {
      const bool stray = unit(rng) < 0.05;
      normals.push_back(stray ? test::random_unit(rng) : glm::normalize(axis + spread * test::random_unit(rng)));
      areas.push_back(stray ? 0.05 * unit(rng) : unit(rng));
    }
    Vec3d sum(0);
    double weight = 0;
    for (size_t k = 0; k < normals.size(); ++k) {
      sum += areas[k] * normals[k];
      weight += areas[k];
    }
    const double len = glm::length(sum);
    if (!(len > 0) || !(weight > 0)) continue;
    const double share = trial % 2 ? 0.01 : 0.1;
    if (!faces_away(eye, box, sum / len, len / weight, share)) continue;
    ++away;
    const std::array<Vec3d, 8> box_corners = corners(box);
    std::vector<Vec3d> points(box_corners.begin(), box_corners.end());
    for (int k = 0; k < 24; ++k) points.push_back(box.lo + Vec3d(unit(rng), unit(rng), unit(rng)) * (box.hi - box.lo));
    for (const Vec3d& p : points) {
      double facing = 0;
      for (size_t k = 0; k < normals.size(); ++k)
        if (glm::dot(normals[k], p - eye) <= 0) facing += areas[k];
      EXPECT_LE(facing, share * weight * (1 + 1e-12)) << "trial " << trial;
    }
  }
  EXPECT_GT(away, 200);
}

Bbox box_around(const Vec3d& c, double half) { return Bbox{c - Vec3d(half), c + Vec3d(half)}; }

bool may_shadow(const ShadowReceivers& r, const Bbox& b) { return r.may_shadow(corners(b), b); }

TEST(ShadowReceivers, BoxesBetweenTheLightAndWhatIsSeen) {
  // Receivers on the plane y = 0 near the origin, each reaching 0.1.
  std::vector<ShadowReceiver> seen;
  for (int i = -5; i <= 5; ++i)
    for (int k = -5; k <= 5; ++k) seen.push_back({Vec3d(0.2 * i, 0, 0.2 * k), 0.1});
  const ShadowReceivers sun = ShadowReceivers::make(directional(Vec3d(0, -1, 0)), seen);
  EXPECT_TRUE(may_shadow(sun, box_around(Vec3d(0.3, 2, -0.4), 0.05)));   // above them
  EXPECT_FALSE(may_shadow(sun, box_around(Vec3d(0.3, -2, -0.4), 0.05)));  // below: the light is above
  EXPECT_FALSE(may_shadow(sun, box_around(Vec3d(5, 2, 0), 0.05)));       // above, beside them
  EXPECT_TRUE(may_shadow(sun, box_around(Vec3d(5, 2, 0), 4.0)));         // a box reaching over them
  // A slanted sun: the shadow of a box at height 2 falls 2 units along x.
  const ShadowReceivers slant = ShadowReceivers::make(directional(Vec3d(1, -1, 0)), seen);
  EXPECT_TRUE(may_shadow(slant, box_around(Vec3d(-2, 2, 0), 0.05)));
  EXPECT_FALSE(may_shadow(slant, box_around(Vec3d(2, 2, 0), 0.05)));
  // A point light above: between it and the receivers, not beyond it.
  const ShadowReceivers bulb = ShadowReceivers::make(point(Vec3d(0, 10, 0)), seen);
  EXPECT_TRUE(may_shadow(bulb, box_around(Vec3d(0.1, 5, 0.1), 0.05)));
  EXPECT_FALSE(may_shadow(bulb, box_around(Vec3d(0.1, 12, 0.1), 0.05)));  // behind the light
  EXPECT_FALSE(may_shadow(bulb, box_around(Vec3d(3, 5, 0), 0.05)));       // off the cone to them
  EXPECT_FALSE(may_shadow(bulb, box_around(Vec3d(0, -1, 0), 0.05)));      // farther than them
  EXPECT_TRUE(may_shadow(bulb, box_around(Vec3d(0, 10, 0), 0.05)));       // holding the light
  // Nothing seen: no shadow shows.
  EXPECT_FALSE(may_shadow(ShadowReceivers::make(directional(Vec3d(0, -1, 0)), {}), box_around(Vec3d(0), 1)));
  // A point light among the receivers (seen all around it): every box may shadow.
  std::vector<ShadowReceiver> around;
  for (int a = 0; a < 8; ++a) around.push_back({Vec3d(std::cos(a * 0.785), 0, std::sin(a * 0.785)), 0.01});
  EXPECT_TRUE(may_shadow(ShadowReceivers::make(point(Vec3d(0)), around), box_around(Vec3d(0, 5, 0), 0.01)));
}

// At the edges: a box that touches a receiver of radius 0 (the point itself
// is on its segment to the light), a box beside the receivers whose edge is
// their farthest extent (the grid's far edge, which rounding may put an ulp
// short of it), and a box with corners that are not numbers.
TEST(ShadowReceivers, BoxesTouchingTheReceiversExactly) {
  const std::vector<ShadowReceiver> one = {{Vec3d(0), 0.0}};
  const ShadowReceivers sun = ShadowReceivers::make(directional(Vec3d(0, -1, 0)), one);
  EXPECT_TRUE(may_shadow(sun, Bbox{Vec3d(-0.5, -1, -0.5), Vec3d(0.5, 0, 0.5)}));
  EXPECT_FALSE(may_shadow(sun, Bbox{Vec3d(-0.5, -1, -0.5), Vec3d(0.5, -1e-9, 0.5)}));
  const double a = -3.0548189331792045e-05, b = 9.362523639122675e-06;
  const std::vector<ShadowReceiver> two = {{Vec3d(0, 0, a), 0.0}, {Vec3d(0, 0, b), 0.0}};
  const ShadowReceivers edge = ShadowReceivers::make(directional(Vec3d(0, -1, 0)), two);
  EXPECT_TRUE(may_shadow(edge, Bbox{Vec3d(-1e-6, 1e-3, b), Vec3d(1e-6, 2e-3, b + 1e-6)}));
  EXPECT_TRUE(may_shadow(edge, Bbox{Vec3d(-1e-6, 1e-3, a - 1e-6), Vec3d(1e-6, 2e-3, a)}));
  for (const Light& l : {directional(Vec3d(0, -1, 0)), point(Vec3d(0, 1, 0))}) {
    const ShadowReceivers sr = ShadowReceivers::make(l, two);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::array<Vec3d, 8> bad;
    bad.fill(Vec3d(nan));
    EXPECT_TRUE(sr.may_shadow(bad, Bbox{Vec3d(nan), Vec3d(nan)}));
  }
}

// Brute force: a box around any point between the light and a point within
// a receiver's reach must be said to may shadow.
TEST(ShadowReceivers, EveryBoxOnASegmentToTheLightMayShadow) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-1, 1), unit(0, 1);
  int said_no = 0, checked = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const bool is_point = trial % 2 == 1;
    const Vec3d centre(10 * u(rng), 10 * u(rng), 10 * u(rng));
    const Light l = is_point ? point(centre + (20 + 20 * unit(rng)) * test::random_unit(rng))
                             : directional(test::random_unit(rng));
    std::vector<ShadowReceiver> rs;
    const int n = 1 + int(200 * unit(rng));
    for (int i = 0; i < n; ++i)
      rs.push_back({centre + 3.0 * Vec3d(u(rng), u(rng), u(rng)), 0.2 * unit(rng) * unit(rng)});
    const ShadowReceivers sr = ShadowReceivers::make(l, rs);
    for (int k = 0; k < 200; ++k) {
      const ShadowReceiver& r = rs[size_t(rng() % rs.size())];
      const Vec3d q = r.point + r.radius * unit(rng) * test::random_unit(rng);
      const Vec3d to_light = is_point ? l.position - q : -l.direction * 50.0;
      const Vec3d x = q + unit(rng) * to_light;
      const double half = 1e-3 + unit(rng) * unit(rng);
      ++checked;
      EXPECT_TRUE(may_shadow(sr, box_around(x, half))) << "trial " << trial << " k " << k;
    }
    // And boxes anywhere: some are said to shadow nothing (the test can fail).
    for (int k = 0; k < 50; ++k) said_no += !may_shadow(sr, box_around(centre + 30.0 * Vec3d(u(rng), u(rng), u(rng)), 0.1));
  }
  EXPECT_EQ(checked, 200 * 200);
  EXPECT_GT(said_no, 2000);
}

}  // namespace
}  // namespace raylod
