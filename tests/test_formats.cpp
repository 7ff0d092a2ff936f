// Formats: the DOF table, cubist-range/1, hand-rig/1, point clouds, pipeline files.
#include <gtest/gtest.h>
#include <pcl/io/ply_io.h>

#include <array>
#include <cmath>
#include <random>
#include <filesystem>
#include <limits>
#include <set>

#include "core/atomic_file.hpp"
#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/png_io.hpp"
#include "core/rig.hpp"
#include "mesh/mesh.hpp"
#include "mesh/point_grid.hpp"
#include "pipeline/options.hpp"
#include "pipeline/stage_options.hpp"
#include "register/registration.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"
#include "test_util.hpp"

using namespace handskin;
namespace fs = std::filesystem;

namespace {

const std::string kFixture = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";

// Expect `fn` to throw InputError whose message contains every needle.
template <class F>
void expect_input_error(F fn, std::initializer_list<std::string> needles) {
  try {
    fn();
    FAIL() << "no error thrown";
  } catch (const InputError& e) {
    for (const auto& n : needles) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << "missing \"" << n << "\" in: " << e.what();
  }
}

RangeScan small_scan() {
  RangeScan s;
  s.meta.scanlines = 5;
  s.meta.points = 7;
  s.meta.x_origin_mm = 1.5;
  s.meta.x_step_mm = 0.5;
  s.meta.y_origin_mm = -2;
  s.meta.y_step_mm = 0.25;
  s.meta.z_origin_mm = 3;
  s.meta.z_step_mm = 0.2;
  s.meta.side = ScanSide::Palm;
  s.meta.notes = "test";
  for (int k = 0; k < 35; ++k) s.values.push_back(static_cast<std::uint16_t>(k % 4 == 0 ? 0 : 1000 + 37 * k));
  return s;
}

std::string meta_text(const std::string& replace_key = "", const std::string& value = "") {
  Json j = Json::parse(scan_meta_to_json_text(small_scan().meta));
  if (!replace_key.empty()) {
    if (value == "<erase>") j.erase(replace_key);
    else j[replace_key] = Json::parse(value);
  }
  return j.dump();
}

std::string gray16_png(int w, int h) {
  Gray16Image img{w, h, std::vector<std::uint16_t>(static_cast<size_t>(w) * h, 500)};
  return encode_gray16_png(img);
}

}  // namespace

TEST(DofTable, CountsNamesAndAliases) {
  EXPECT_EQ(joints().size(), 25u);
  EXPECT_EQ(dofs().size(), 35u);
  std::set<std::string> names;
  for (const auto& d : dofs()) names.insert(d.name);
  EXPECT_EQ(names.size(), 35u);
  EXPECT_EQ(dofs()[*dof_index("I2.flex")].name, "index.mcp.flex");
  EXPECT_EQ(dofs()[*dof_index("l4.flex")].name, "little.dip.flex");
  EXPECT_EQ(dofs()[*dof_index("T3.flex")].name, "thumb.ip.flex");
  EXPECT_EQ(dofs()[*dof_index("T1.abd")].name, "thumb.cmc.abd");
  EXPECT_EQ(*dof_index("wrist.rz"), 5);
  EXPECT_FALSE(dof_index("thumb.dip.flex"));
  EXPECT_FALSE(dof_index("index.mcp"));
  EXPECT_EQ(joints()[*joint_index("L2")].name, std::string("pinky-finger-phalanx-proximal"));
  // Parents come before children, every finger chain starts at the wrist.
  for (int i = 1; i < kJointCount; ++i) EXPECT_LT(joints()[i].parent, i);
  EXPECT_EQ(finger_chain(Finger::Thumb).size(), 4u);
  EXPECT_EQ(finger_chain(Finger::Little).size(), 5u);
}

TEST(CubistRange, RoundTrip) {
  const std::string dir = test::temp_dir("scan");
  const RangeScan s = small_scan();
  save_scan(dir + "/a", s);
  const RangeScan r = load_scan(dir + "/a");
  EXPECT_EQ(r.values, s.values);
  EXPECT_EQ(r.meta.scanlines, 5);
  EXPECT_EQ(r.meta.points, 7);
  EXPECT_DOUBLE_EQ(r.meta.x_origin_mm, 1.5);
  EXPECT_DOUBLE_EQ(r.meta.y_step_mm, 0.25);
  EXPECT_EQ(r.meta.side, ScanSide::Palm);
  EXPECT_EQ(r.meta.notes, "test");
  // Position of sample (i, j) follows the spec's formulas.
  const Eigen::Vector3d p = r.position(2, 3);
  EXPECT_DOUBLE_EQ(p.x(), 1.5 + 2 * 0.5);
  EXPECT_DOUBLE_EQ(p.y(), -2 + 3 * 0.25);
  EXPECT_NEAR(p.z(), 3 + r.at(2, 3) * 0.2, 1e-12);
  // No temporary files left beside the outputs.
  size_t files = 0;
  for (auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 2u);
}

TEST(CubistRange, AScanIsNamedByItsStemOrEitherFile) {
  const std::string dir = test::temp_dir("scan_stem");
  EXPECT_EQ(scan_stem(dir + "/a"), dir + "/a");
  EXPECT_EQ(scan_stem(dir + "/a.json"), dir + "/a");
  EXPECT_EQ(scan_stem(dir + "/a.png"), dir + "/a");
  EXPECT_EQ(scan_stem(dir + "/a.photo.png"), dir + "/a.photo");  // names a stem: its error will say so
  // A stem that itself ends in ".json" (its sidecar "x.json.json" is there) is kept.
  save_scan(dir + "/x.json", small_scan());
  EXPECT_EQ(scan_stem(dir + "/x.json"), dir + "/x.json");
  EXPECT_EQ(load_scan(scan_stem(dir + "/x.json.png")).values, small_scan().values);
}

TEST(CubistRange, ReadsTheFixture) {
  const RangeScan back = load_scan(kFixture + "back");
  EXPECT_EQ(back.meta.scanlines, 512);
  EXPECT_EQ(back.meta.points, 512);
  EXPECT_EQ(back.meta.side, ScanSide::Back);
  EXPECT_NEAR(back.meta.x_step_mm, 250.0 / 512, 1e-12);
  EXPECT_GT(back.count_valid(), 100000u);
}

TEST(CubistRange, BadPngs) {
  const std::string meta = meta_text();
  const std::string good = gray16_png(7, 5);
  expect_input_error([&] { decode_scan("hello, not a png", "x.png", meta, "x.json"); }, {"x.png", "not a PNG"});
  expect_input_error([&] { decode_scan(good.substr(0, good.size() / 2), "x.png", meta, "x.json"); },
                     {"x.png", "unreadable PNG"});
  expect_input_error([&] { decode_scan(test::make_png(7, 5, 8, 0, std::vector<std::uint8_t>(35, 9)), "x.png", meta, "x.json"); },
                     {"x.png", "16-bit", "8-bit"});
  expect_input_error([&] { decode_scan(test::make_png(7, 5, 16, 2, std::vector<std::uint8_t>(7 * 5 * 6, 9)), "x.png", meta, "x.json"); },
                     {"x.png", "RGB"});
  expect_input_error([&] { decode_scan(test::make_png(7, 5, 16, 4, std::vector<std::uint8_t>(7 * 5 * 4, 9)), "x.png", meta, "x.json"); },
                     {"x.png", "alpha"});
  expect_input_error([&] { decode_scan(gray16_png(6, 5), "x.png", meta, "x.json"); }, {"x.json", "points", "6 columns"});
  expect_input_error([&] { decode_scan(gray16_png(7, 4), "x.png", meta, "x.json"); }, {"x.json", "scanlines", "4 rows"});
  Gray16Image empty{7, 5, std::vector<std::uint16_t>(35, 0)};
  expect_input_error([&] { decode_scan(encode_gray16_png(empty), "x.png", meta, "x.json"); }, {"x.png", "empty scan"});
}

TEST(CubistRange, BadMetadata) {
  const std::string png = gray16_png(7, 5);
  auto with = [&](const std::string& key, const std::string& v) {
    return [=] { decode_scan(png, "x.png", meta_text(key, v), "x.json"); };
  };
  expect_input_error(with("z_step_mm", "<erase>"), {"x.json", "missing key 'z_step_mm'"});
  expect_input_error(with("x_step_mm", "\"0.5\""), {"x.json", "'x_step_mm'", "number"});
  expect_input_error(with("x_step_mm", "0"), {"x.json", "'x_step_mm'", "> 0"});
  expect_input_error(with("y_step_mm", "-0.1"), {"x.json", "'y_step_mm'", "> 0"});
  // JSON has no NaN or infinity; such values are parse errors that point at the key.
  std::string inf_meta = meta_text();
  inf_meta.replace(inf_meta.find("\"z_origin_mm\":") + 14, 3, "1e999");
  expect_input_error([&] { decode_scan(png, "x.png", inf_meta, "x.json"); }, {"x.json", "not valid JSON", "z_origin_mm"});
  std::string nan_meta = meta_text();
  nan_meta.replace(nan_meta.find("\"x_step_mm\":") + 12, 3, "NaN");
  expect_input_error([&] { decode_scan(png, "x.png", nan_meta, "x.json"); }, {"x.json", "not valid JSON", "x_step_mm"});
  expect_input_error(with("scanlines", "5.5"), {"x.json", "'scanlines'", "integer"});
  expect_input_error(with("points", "0"), {"x.json", "'points'"});
  expect_input_error(with("side", "\"top\""), {"x.json", "'side'"});
  expect_input_error(with("format", "\"cubist-range/2\""), {"x.json", "'format'"});
  expect_input_error([&] { decode_scan(png, "x.png", "[1,2]", "x.json"); }, {"x.json", "object"});
  expect_input_error([&] { load_scan("/nonexistent/stem"); }, {"/nonexistent/stem.json", "no such file"});
  // Unknown keys are ignored, per the spec.
  EXPECT_NO_THROW(decode_scan(png, "x.png", meta_text("vendor_extra", "42"), "x.json"));
}

TEST(HandRig, RoundTripAndAliases) {
  const Rig rig = load_rig(kFixture + "rig.json");
  EXPECT_EQ(rig.frame, "palm");
  ASSERT_TRUE(rig.palm_normal);
  const Rig back = parse_rig(rig_to_json_text(rig), "mem");
  for (int i = 0; i < kJointCount; ++i) EXPECT_EQ(back.joints[i], rig.joints[i]);
  // A unit palm_normal comes back bit for bit, also one that normalizing again would move (as
  // the placement's, written to rig_auto.json: H12-s3 of the family's was, and `patches
  // --skin-dir` built another skin on it than its run had); one that is not unit is normalized.
  Rig tilted = rig;
  int moved = 0;
  for (int k = 1; k <= 200; ++k) {
    const Eigen::Vector3d n = Eigen::Vector3d(0.001 * k, 0.0079 + 1e-5 * k, -1.0).normalized();
    if (Eigen::Vector3d(n.normalized()) != n) ++moved;
    tilted.palm_normal = n;
    ASSERT_EQ(*parse_rig(rig_to_json_text(tilted), "mem").palm_normal, n) << k;
  }
  EXPECT_GT(moved, 0);  // the test holds such normals
  tilted.palm_normal = Eigen::Vector3d(0, 0, -2);
  EXPECT_EQ(*parse_rig(rig_to_json_text(tilted), "mem").palm_normal, Eigen::Vector3d(0, 0, -1));
  // Thesis aliases are accepted as joint names.
  Json j = Json::parse(rig_to_json_text(rig));
  j["joints"]["I2"] = j["joints"]["index-finger-phalanx-proximal"];
  j["joints"].erase("index-finger-phalanx-proximal");
  EXPECT_EQ(parse_rig(j.dump(), "mem").joints[*joint_index("I2")], rig.joints[*joint_index("I2")]);
}

TEST(HandRig, BadRigs) {
  const std::string good = read_file(kFixture + "rig.json");
  auto edit = [&](auto fn) {
    Json j = Json::parse(good);
    fn(j);
    return j.dump();
  };
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["joints"].erase("ring-finger-tip"); }), "r.json"); },
                     {"r.json", "missing joint 'ring-finger-tip'"});
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["joints"]["sixth-finger-tip"] = {1, 2, 3}; }), "r.json"); },
                     {"r.json", "unknown joint 'sixth-finger-tip'"});
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["joints"]["wrist"] = {1, 2}; }), "r.json"); },
                     {"r.json", "'wrist'", "3 numbers"});
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["joints"]["wrist"] = {1, "a", 2}; }), "r.json"); },
                     {"r.json", "'wrist'"});
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["joints"]["L2"] = j["joints"]["pinky-finger-phalanx-proximal"]; }), "r.json"); },
                     {"r.json", "given twice"});
  expect_input_error([&] {
    parse_rig(edit([](Json& j) { j["joints"]["index-finger-tip"] = j["joints"]["index-finger-phalanx-distal"]; }), "r.json");
  }, {"r.json", "'index-finger-tip'", "same place"});
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["palm_normal"] = {0, 0, 0}; }), "r.json"); },
                     {"r.json", "palm_normal"});
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["format"] = "hand-rig/9"; }), "r.json"); }, {"r.json", "format"});
  expect_input_error([&] { parse_rig(edit([](Json& j) { j["units"] = "cm"; }), "r.json"); }, {"r.json", "units"});
  // Duplicated key in the raw text (a JSON parser would keep only one).
  std::string dup = good;
  const size_t at = dup.find("\"wrist\"");
  ASSERT_NE(at, std::string::npos);
  dup.insert(at, "\"wrist\": [0, 0, 0],\n    ");
  expect_input_error([&] { parse_rig(dup, "r.json"); }, {"r.json", "'wrist'", "twice"});
  std::string inf = good;
  const size_t c = inf.find('[', inf.find("\"wrist\""));
  inf.replace(c, inf.find(']', c) - c + 1, "[1e999, 0, 0]");
  expect_input_error([&] { parse_rig(inf, "r.json"); }, {"r.json", "not valid JSON", "1e999"});
}

TEST(Clouds, OrganisedLayoutAndFileRoundTrip) {
  const RangeScan s = small_scan();
  const Cloud::Ptr org = scan_to_organized_cloud(s);
  EXPECT_EQ(org->width, 7u);
  EXPECT_EQ(org->height, 5u);
  EXPECT_FALSE(org->is_dense);
  EXPECT_TRUE(std::isnan(org->at(0, 0).x));  // value 0 = no return
  const Eigen::Vector3d p = s.position(1, 2);
  EXPECT_FLOAT_EQ(org->at(2, 1).x, static_cast<float>(p.x()));
  EXPECT_FLOAT_EQ(org->at(2, 1).z, static_cast<float>(p.z()));
  const Cloud::Ptr dense = dense_copy(*org);
  EXPECT_EQ(dense->size(), s.count_valid());
  const std::string dir = test::temp_dir("cloud");
  for (const char* ext : {".ply", ".pcd"}) {
    save_cloud(dir + "/c" + ext, *dense);
    const Cloud::Ptr back = load_cloud(dir + "/c" + ext);
    ASSERT_EQ(back->size(), dense->size());
    for (size_t k = 0; k < back->size(); ++k) EXPECT_FLOAT_EQ(back->points[k].y, dense->points[k].y);
  }
  // An organised cloud with NaNs loads as its measured points (PLY or PCD); anywhere else a
  // NaN is refused, naming the point.
  save_cloud(dir + "/org.pcd", *org);
  EXPECT_EQ(load_cloud(dir + "/org.pcd")->size(), s.count_valid());
  save_cloud(dir + "/org.ply", *org);
  EXPECT_EQ(load_cloud(dir + "/org.ply")->size(), s.count_valid());
  Cloud loose = *dense;
  loose.points[3].y = std::numeric_limits<float>::quiet_NaN();
  loose.is_dense = false;
  save_cloud(dir + "/loose.ply", loose);
  expect_input_error([&] { load_cloud(dir + "/loose.ply"); }, {"loose.ply", "point 3", "non-finite"});
  test::write_text(dir + "/junk.ply", "ply\nformat nonsense\n");
  expect_input_error([&] { load_cloud(dir + "/junk.ply"); }, {"junk.ply"});
  expect_input_error([&] { load_cloud(dir + "/c.las"); }, {"c.las", "extension"});
  expect_input_error([&] { load_cloud(dir + "/missing.ply"); }, {"missing.ply", "no such file"});
}

// merged.ply is read by the project's one cloud reader: the points, normals and sides as
// written; a cloud that is not a merged one, or whose labels are not sides, is refused.
TEST(Clouds, MergedCloudReadsBackAndBadOnesAreRefused) {
  const std::string dir = test::temp_dir("merged-read");
  MergedCloud m;
  for (int k = 0; k < 4; ++k) {
    pcl::PointXYZLNormal q;
    q.x = 1.5f * k, q.y = -2.25f, q.z = 0.125f * k;
    q.normal_x = 0, q.normal_y = 0.6f, q.normal_z = 0.8f;
    q.label = k % 2 ? kSideBack : kSidePalm;
    q.curvature = 0;
    m.push_back(q);
  }
  save_merged(dir + "/m.ply", m);
  save_merged(dir + "/m.pcd", m);
  // handskin's own writer (docs/formats.md): one vertex element, x y z nx ny nz label, 28 bytes a
  // point; PCL's writer (merged.ply before 2026-11-28: a label before the normals, a curvature
  // and a camera element) is read alike.
  const std::string ply = read_file(dir + "/m.ply");
  const std::string header = "ply\nformat binary_little_endian 1.0\ncomment handskin\nelement vertex 4\n"
                             "property float x\nproperty float y\nproperty float z\nproperty float nx\n"
                             "property float ny\nproperty float nz\nproperty uint label\nend_header\n";
  EXPECT_EQ(ply.substr(0, header.size()), header);
  EXPECT_EQ(ply.size(), header.size() + 4 * 28);
  pcl::io::savePLYFileBinary(dir + "/pcl.ply", m);
  for (const char* f : {"m.ply", "m.pcd", "pcl.ply"}) {
    const MergedArrays a = read_merged(dir + "/" + f);
    ASSERT_EQ(a.points.size(), 4u) << f;
    for (size_t k = 0; k < 4; ++k) {
      EXPECT_EQ(a.points[k], m[k].getVector3fMap().cast<double>()) << f;
      EXPECT_EQ(a.normals[k], m[k].getNormalVector3fMap().cast<double>()) << f;
      EXPECT_EQ(a.sides[k], m[k].label) << f;
    }
  }
  m[2].label = 7;
  save_merged(dir + "/bad.ply", m);
  expect_input_error([&] { read_merged(dir + "/bad.ply"); }, {"bad.ply", "point 2", "side label 7"});
  m[2].label = kSidePalm;
  m[1].normal_y = std::numeric_limits<float>::infinity();
  save_merged(dir + "/inf.ply", m);
  expect_input_error([&] { read_merged(dir + "/inf.ply"); }, {"inf.ply", "point 1", "not finite"});
  save_cloud(dir + "/points.ply", std::vector<Eigen::Vector3d>{{0, 0, 0}, {1, 0, 0}});
  expect_input_error([&] { read_merged(dir + "/points.ply"); }, {"points.ply", "no normals"});
}

TEST(Clouds, ScanToCloudToScanIsExact) {
  const RangeScan s = load_scan(kFixture + "palm");
  size_t dropped = 1;
  const RangeScan back = cloud_to_scan(*dense_copy(*scan_to_organized_cloud(s)), s.meta, &dropped);
  EXPECT_EQ(dropped, 0u);
  EXPECT_EQ(back.values, s.values);
  // Points off the grid are dropped and counted; the highest point of a cell wins.
  Cloud c;
  c.push_back(pcl::PointXYZ(-50.0f, 0.0f, 10.0f));
  c.push_back(pcl::PointXYZ(2.0f, -1.0f, 10.0f));   // sample (1, 4) of small_scan's grid
  c.push_back(pcl::PointXYZ(2.1f, -0.95f, 12.0f));  // the same sample, higher
  const RangeScan r = cloud_to_scan(c, small_scan().meta, &dropped);
  EXPECT_EQ(dropped, 1u);
  EXPECT_EQ(r.count_valid(), 1u);
  EXPECT_EQ(r.at(1, 4), std::lround((12.0 - 3.0) / 0.2));
}

TEST(Pipeline, ShippedFileEqualsBuiltInDefaults) {
  const std::string file = std::string(HANDSKIN_SOURCE_DIR) + "/pipelines/cubist.json";
  const PipelineOptions o = load_pipeline(file);
  EXPECT_EQ(pipeline_to_json(o), pipeline_to_json(PipelineOptions{}));
  EXPECT_EQ(o.slicing.planes, 50);
  EXPECT_EQ(o.slicing.points_per_segment, 10);
  EXPECT_EQ(o.patches.count, 96);
  EXPECT_FALSE(o.markers.radius_mm.has_value());  // estimated from the scans (docs/registration.md)
  Json j = pipeline_to_json(o);
  j["markers"]["radius_mm"] = 3.0;
  EXPECT_DOUBLE_EQ(parse_pipeline(j, "p.json").markers.radius_mm.value(), 3.0);
  EXPECT_TRUE(registration_options(parse_pipeline(j, "p.json")).estimate_radius == false);
  EXPECT_TRUE(registration_options(o).estimate_radius);
}

TEST(Pipeline, BadFiles) {
  Json j = pipeline_to_json(PipelineOptions{});
  j["slicing"]["planez"] = 3;
  expect_input_error([&] { parse_pipeline(j, "p.json"); }, {"p.json", "slicing.planez"});
  j = pipeline_to_json(PipelineOptions{});
  j["markers"]["radius_mm"] = -1.0;
  expect_input_error([&] { parse_pipeline(j, "p.json"); }, {"p.json", "radius_mm"});
  j = pipeline_to_json(PipelineOptions{});
  j["registration"]["icp_gate"] = 1.0;  // a typo of icp_gate_mm
  expect_input_error([&] { parse_pipeline(j, "p.json"); }, {"p.json", "registration.icp_gate"});
  j = pipeline_to_json(PipelineOptions{});
  j["registration"]["icp_trim"] = 1.5;
  expect_input_error([&] { parse_pipeline(j, "p.json"); }, {"p.json", "registration.icp_trim"});
  j = pipeline_to_json(PipelineOptions{});
  j["surfacing"] = Json::object();  // no such stage
  expect_input_error([&] { parse_pipeline(j, "p.json"); }, {"p.json", "surfacing"});
  j = pipeline_to_json(PipelineOptions{});
  j["patches"]["c1_weight"] = -1.0;
  expect_input_error([&] { parse_pipeline(j, "p.json"); }, {"p.json", "patches.c1_weight"});
}

TEST(Pipeline, PatchContinuityReachesTheFit) {
  Json j = pipeline_to_json(PipelineOptions{});
  EXPECT_EQ(patch_options(PipelineOptions{}).c1_weight, PatchOptions{}.c1_weight);
  EXPECT_EQ(patch_options(PipelineOptions{}).fairness, PatchOptions{}.fairness);
  j["patches"]["c1_weight"] = 0.0;
  j["patches"]["fairness"] = 0.01;
  const PatchOptions p = patch_options(parse_pipeline(j, "p.json"));
  EXPECT_EQ(p.c1_weight, 0.0);
  EXPECT_EQ(p.fairness, 0.01);
}

// A mesh header that declares more than its file can hold is refused at once (OpenMesh's
// readers reserve what a header declares: 10^11 vertices filled memory for minutes).
TEST(Formats, AMeshHeaderDeclaringMoreThanItsFileHoldsIsRefusedAtOnce) {
  const std::string dir = test::temp_dir("declared");
  const std::vector<std::pair<std::string, std::string>> files = {
      {"a.ply", "ply\nformat ascii 1.0\nelement vertex 99999999999\nend_header\n"},
      {"b.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\n"
                "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"},
      {"c.off", "OFF\n100000000000 1 0\n"},
      {"d.stl", std::string(80, '\0') + std::string("\xff\xff\xff\x7f", 4)}};
  for (const auto& [name, text] : files) {
    write_file_atomic(dir + "/" + name, text);
    const std::string e = test::input_error_of([&] { load_mesh(dir + "/" + name); });
    EXPECT_NE(e.find("its header declares"), std::string::npos) << name << ": " << e;
  }
  // a well-formed small file still reads
  write_file_atomic(dir + "/ok.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(load_mesh(dir + "/ok.off").faces.size(), 1u);
}

// A PNG header's own figures in the message (libpng says only "Invalid IHDR data").
TEST(Formats, APngHeaderOfAnEmptyOrHugeImageIsNamed) {
  const std::string empty = test::make_png(0, 4, 16, 0, {});
  EXPECT_NE(test::input_error_of([&] { decode_gray16_png(empty, "e.png"); }).find("declares an empty image (0 x 4 pixels)"),
            std::string::npos);
  const std::string huge = test::make_png(20000, 1, 16, 0, std::vector<std::uint8_t>(40000, 0));
  EXPECT_NE(test::input_error_of([&] { decode_gray16_png(huge, "h.png", 16384); }).find("20000 x 1 pixels, larger than 16384"),
            std::string::npos);
}

// The hash grid's answers are a brute-force search's: the nearest point within a radius (ties:
// the lower index), whether any lies within it, and every point within it — in the order the
// grid reports them (cells shell by shell, each cell's points by ascending index), which the
// callers' sums and first-found choices depend on. Clouds with clusters, duplicates, points on
// cell boundaries, negative coordinates, and more cells than the table first has room for.
TEST(PointGrid, AnswersAsABruteForceSearch) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-40, 40), small(-0.3, 0.3);
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<Eigen::Vector3d> pts;
    const int n = trial == 0 ? 0 : trial == 1 ? 5 : 3000 * trial;
    for (int k = 0; k < n; ++k) {
      if (k % 7 == 3 && !pts.empty()) pts.push_back(pts[static_cast<size_t>(k) / 2]);  // a duplicate: a tie
      else if (k % 5 == 0) pts.push_back(Eigen::Vector3d(std::round(u(rng)), std::round(u(rng)), 2.0));  // on cell walls
      else if (k % 3 == 0) pts.push_back(Eigen::Vector3d(10 + small(rng), -10 + small(rng), small(rng)));  // a cluster
      else pts.push_back(Eigen::Vector3d(u(rng), u(rng), u(rng)));
    }
    const double cell = trial == 3 ? 0.5 : 1.5;
    const PointGrid grid(pts, cell);
    for (int q = 0; q < 400; ++q) {
      const Eigen::Vector3d x = q % 4 == 0 && !pts.empty() ? pts[static_cast<size_t>(q) % pts.size()]
                                : q % 4 == 1 ? Eigen::Vector3d(10 + small(rng), -10 + small(rng), small(rng))
                                             : Eigen::Vector3d(u(rng), u(rng), u(rng));
      const double r = q % 3 == 0 ? 0.7 : q % 3 == 1 ? 3.0 : 9.0;
      int best = -1;
      double bd2 = r * r;
      std::set<int> inside;
      for (size_t k = 0; k < pts.size(); ++k) {
        const double d2 = (pts[k] - x).squaredNorm();
        if (d2 < bd2) bd2 = d2, best = static_cast<int>(k);  // strict: the lower index keeps a tie
        if (d2 <= r * r) inside.insert(static_cast<int>(k));
      }
      ASSERT_EQ(grid.nearest(x, r), best) << "trial " << trial << " query " << q;
      bool any = false;
      for (size_t k = 0; k < pts.size(); ++k) any = any || (pts[k] - x).squaredNorm() < r * r;
      ASSERT_EQ(grid.any_within(x, r), any);
      std::vector<int> got;
      grid.within(x, r, [&](int k) { got.push_back(k); });
      ASSERT_EQ(std::set<int>(got.begin(), got.end()), inside);
      ASSERT_EQ(got.size(), inside.size()) << "a point reported twice";
      // The order: by cell shell, then by cell (x, y, z ascending within the shell), then by index.
      const auto cell_of = [&](int k) {
        return Eigen::Vector3i(static_cast<int>(std::floor(pts[k].x() / cell)), static_cast<int>(std::floor(pts[k].y() / cell)),
                               static_cast<int>(std::floor(pts[k].z() / cell)));
      };
      const Eigen::Vector3i c(static_cast<int>(std::floor(x.x() / cell)), static_cast<int>(std::floor(x.y() / cell)),
                              static_cast<int>(std::floor(x.z() / cell)));
      const auto rank = [&](int k) {
        const Eigen::Vector3i d = cell_of(k) - c;
        return std::array<int, 5>{std::max({std::abs(d.x()), std::abs(d.y()), std::abs(d.z())}), d.x(), d.y(), d.z(), k};
      };
      for (size_t i = 1; i < got.size(); ++i) ASSERT_LT(rank(got[i - 1]), rank(got[i])) << "trial " << trial << " query " << q;
    }
  }
}
