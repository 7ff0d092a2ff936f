// The synthetic CUBIST scanner against geometry with exact answers.
#include <gtest/gtest.h>

#include <cmath>

#include "core/errors.hpp"
#include "synth/replica.hpp"
#include "synth/scanner.hpp"
#include "test_util.hpp"

using namespace handskin;
using test::add_box;

namespace {
constexpr double kDeg = M_PI / 180.0;


ScannerOptions exact_options() {
  ScannerOptions o;
  o.noise_sigma_mm = 0.0;
  return o;
}
}  // namespace

TEST(Scanner, BoxHeightsAndLaserShadow) {
  const ScannerOptions o = exact_options();
  Scene scene;
  const double top = 35.0;
  add_box(&scene, {100, 80, o.table_height_mm}, {140, 110, top}, 0);
  const ScanSimulation sim = simulate_scan(scene, o, ScanSide::Back, 1);
  const double shadow = (top - o.table_height_mm) * std::tan(o.laser_tilt_deg * kDeg);  // width on the table
  int checked_top = 0, checked_shadow = 0, checked_table = 0;
  for (int i = 0; i < o.scanlines; ++i)
    for (int j = 0; j < o.points; ++j) {
      const double x = i * o.x_step(), y = j * o.y_step();
      const std::uint16_t v = sim.scan.at(i, j);
      const bool inside_y = y > 80 + 0.5 && y < 110 - 0.5;
      if (x > 100.5 && x < 139.5 && inside_y) {
        EXPECT_EQ(v, std::lround(top / o.z_step_mm)) << "top at " << x << "," << y;
        ++checked_top;
      } else if (inside_y && x > 100 - shadow + 0.5 && x < 99.5) {
        EXPECT_EQ(v, 0) << "expected laser shadow at x=" << x;
        ++checked_shadow;
      } else if (inside_y && (x < 100 - shadow - 0.5 || x > 140.5)) {
        EXPECT_EQ(v, std::lround(o.table_height_mm / o.z_step_mm)) << "table at x=" << x;
        ++checked_table;
      }
    }
  EXPECT_GT(checked_top, 5000);
  EXPECT_GT(checked_shadow, 500);
  EXPECT_GT(checked_table, 10000);
}

TEST(Scanner, SphereHeightsAndSteepnessLimit) {
  const ScannerOptions o = exact_options();
  Scene scene;
  const Eigen::Vector3d c(60, 60, o.table_height_mm + 21);
  const double r = 20;
  std::vector<Eigen::Vector3d> v;
  std::vector<std::array<int, 3>> f;
  icosphere(c, r, 6, &v, &f);
  scene.add(v, f, 0);
  const ScanSimulation sim = simulate_scan(scene, o, ScanSide::Back, 1);
  const Eigen::Vector3d L = o.laser_direction();
  const double lit = std::cos((o.max_incidence_deg - 2) * kDeg), dark = std::cos((o.max_incidence_deg + 2) * kDeg);
  int seen = 0, unseen = 0;
  for (int i = 0; i < o.scanlines; ++i)
    for (int j = 0; j < o.points; ++j) {
      const double x = i * o.x_step(), y = j * o.y_step();
      const double d2 = (x - c.x()) * (x - c.x()) + (y - c.y()) * (y - c.y());
      if (d2 > (r - 0.3) * (r - 0.3)) continue;
      const double h = std::sqrt(r * r - d2);
      const Eigen::Vector3d n = Eigen::Vector3d(x - c.x(), y - c.y(), h) / r;
      const std::uint16_t val = sim.scan.at(i, j);
      if (n.z() > lit && n.dot(L) > lit) {
        ASSERT_NE(val, 0) << "no return where the sphere faces camera and laser, at " << x << "," << y;
        // Quantisation (half a step) plus the icosphere's faceting.
        EXPECT_NEAR(val * o.z_step_mm, c.z() + h, 0.5 * o.z_step_mm + 0.02);
        ++seen;
      } else if (n.z() < dark || n.dot(L) < dark) {
        EXPECT_EQ(val, 0) << "return past the steepness limit at " << x << "," << y;
        ++unseen;
      }
    }
  EXPECT_GT(seen, 3000);
  EXPECT_GT(unseen, 100);
}

TEST(Scanner, NoiseTiltAndDeterminism) {
  ScannerOptions o;
  o.noise_sigma_mm = 0.05;
  o.table_tilt_deg = 1.0;
  Scene scene;
  add_box(&scene, {10, 10, 0}, {20, 20, 40}, 0);
  const ScanSimulation a = simulate_scan(scene, o, ScanSide::Palm, 7);
  const ScanSimulation b = simulate_scan(scene, o, ScanSide::Palm, 7);
  const ScanSimulation c = simulate_scan(scene, o, ScanSide::Palm, 8);
  EXPECT_EQ(a.scan.values, b.scan.values);
  EXPECT_NE(a.scan.values, c.scan.values);
  EXPECT_EQ(a.scan.meta.side, ScanSide::Palm);
  // Residual of the table against its true tilted plane: noise and quantisation together.
  double sum = 0, sum2 = 0;
  size_t n = 0;
  for (int i = 0; i < o.scanlines; ++i)
    for (int j = 0; j < o.points; ++j) {
      const double x = i * o.x_step(), y = j * o.y_step();
      if (x < 40 && y < 40) continue;  // away from the box and its shadow
      ASSERT_NE(a.scan.at(i, j), 0);
      const double e = a.scan.at(i, j) * o.z_step_mm - o.table_z(x);
      sum += e;
      sum2 += e * e;
      ++n;
    }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  const double expected = std::sqrt(0.05 * 0.05 + o.z_step_mm * o.z_step_mm / 12);
  EXPECT_NEAR(mean, 0.0, 0.005);
  EXPECT_NEAR(sd, expected, 0.01);
}

TEST(Scanner, RejectsBadOptions) {
  ScannerOptions o;
  std::string err;
  o.z_step_mm = 0;
  EXPECT_FALSE(o.IsValid(&err));
  o = ScannerOptions{};
  o.max_incidence_deg = 95;
  EXPECT_FALSE(o.IsValid(&err));
  EXPECT_NE(err.find("max_incidence_deg"), std::string::npos);
  EXPECT_THROW(simulate_scan(Scene{}, o, ScanSide::Back, 1), InputError);
}
