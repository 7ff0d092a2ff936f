// The skin's texture (issue 15, item 5): the scanner's photos, the bake from both photos, the
// texture in skin.glb and in the pictures, and bad photos.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/json_util.hpp"
#include "core/png_io.hpp"
#include "core/rig.hpp"
#include "render/preview.hpp"
#include "render/raster.hpp"
#include "rigging/gltf.hpp"
#include "synth/albedo.hpp"
#include "test_util.hpp"

using namespace handskin;
namespace fs = std::filesystem;

namespace {
const std::string kBin = HANDSKIN_BINARY, kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";

const std::string& fixture_run() { return test::default_fixture_run(); }

Eigen::Vector3d texel(const TextureMap& t, const Eigen::Vector2f& uv) {
  const int x = std::clamp(static_cast<int>(uv.x() * t.size), 0, t.size - 1);
  const int y = std::clamp(static_cast<int>(uv.y() * t.size), 0, t.size - 1);
  const std::uint8_t* c = &t.rgb[(static_cast<size_t>(y) * t.size + x) * 3];
  return {double(c[0]), double(c[1]), double(c[2])};
}
}  // namespace

// The baked colour against the hand's true colour: the albedo the synthetic camera photographed,
// evaluated where each face's centre lies (the skin is within a few tenths of a millimetre of
// the true surface, the creases half a millimetre wide).
TEST(Texture, TheFixturesSkinTakesTheHandsOwnColoursFromBothPhotos) {
  const RiggedSkin s = read_skin_glb(fixture_run() + "/skin.glb");
  ASSERT_FALSE(s.texture.empty());
  ASSERT_EQ(s.texture.corner_uv.size(), s.mesh.faces.size());
  EXPECT_EQ(s.texture.size, 1024);
  const Rig rig = load_rig(kFix + "rig.json");
  const Eigen::Isometry3d T = hand_frame_from_rig(rig);
  Rig rig_hand = rig;
  for (auto& j : rig_hand.joints) j = T * j;
  const SkinAlbedo albedo(rig_hand);
  std::vector<double> err;
  size_t flat = 0;
  for (size_t f = 0; f < s.mesh.faces.size(); ++f) {
    const auto& c = s.texture.corner_uv[f];
    if (c[0] == c[1] && c[1] == c[2]) {  // the flat block: faces neither camera sees
      ++flat;
      continue;
    }
    const auto& t = s.mesh.faces[f];
    const Eigen::Vector3d p = (s.mesh.vertices[t[0]] + s.mesh.vertices[t[1]] + s.mesh.vertices[t[2]]) / 3.0;
    const Eigen::Vector3d n = (s.mesh.vertices[t[1]] - s.mesh.vertices[t[0]]).cross(s.mesh.vertices[t[2]] - s.mesh.vertices[t[0]]).normalized();
    const Eigen::Vector3d truth = 255.0 * albedo.colour(T * p, T.linear() * n).cast<double>();
    const Eigen::Vector3d got = texel(s.texture, (c[0] + c[1] + c[2]) / 3.0f);
    err.push_back((got - truth).cwiseAbs().maxCoeff());
  }
  std::sort(err.begin(), err.end());
  double mean = 0;
  for (double e : err) mean += e;
  mean /= err.size();
  const double p95 = err[err.size() * 95 / 100];
  std::printf("texture vs the true albedo over %zu faces: mean %.1f, p95 %.1f, max %.1f (0-255); %zu faces in the flat block\n",
              err.size(), mean, p95, err.back(), flat);
  EXPECT_LT(mean, 6.0);
  EXPECT_LT(p95, 20.0);
  EXPECT_LT(flat, s.mesh.faces.size() / 20);
  // The report's figures: both photos used, a blend across the flanks, little unseen.
  const Json report = load_json_object(fixture_run() + "/report.json");
  const Json* stage = test::report_stage(report, "texture");
  ASSERT_NE(stage, nullptr);
  EXPECT_GT((*stage)["area_palm_photo_only"].get<double>(), 0.35);
  EXPECT_GT((*stage)["area_back_photo_only"].get<double>(), 0.35);
  EXPECT_GT((*stage)["area_blended"].get<double>(), 0.03);
  // Unseen: 5.2 % of the area until the skin's unseen arcs were bridged by the mean of two
  // guesses (docs/skin.md, step 4), 6.0 % since: the flanks that no scan saw came in toward
  // the true skin, and the steeper skin beside them turned from both cameras. The bound was
  // 6 %; it is 6.5 %.
  EXPECT_LT((*stage)["area_unseen"].get<double>(), 0.065);
  EXPECT_TRUE(fs::exists(fixture_run() + "/texture.png"));
}

TEST(Texture, SkinGlbCarriesTheTextureAndGivesBackTheSkinItWasMadeFrom) {
  const RiggedSkin s = read_skin_glb(fixture_run() + "/skin.glb");
  const Mesh skin = load_mesh(fixture_run() + "/skin.ply");
  ASSERT_EQ(s.mesh.vertices.size(), skin.n_vertices());  // the seam copies folded back
  const auto faces = skin.faces;
  ASSERT_EQ(s.mesh.faces.size(), faces.size());
  for (size_t f = 0; f < faces.size(); ++f) ASSERT_EQ(s.mesh.faces[f], faces[f]);
  // Written again and read again: the same mesh, texture and coordinates.
  const std::string dir = test::temp_dir("texture-glb");
  const auto bytes = skin_glb(s);
  write_file_atomic(dir + "/again.glb", std::string(bytes.begin(), bytes.end()));
  const RiggedSkin t = read_skin_glb(dir + "/again.glb");
  EXPECT_EQ(t.mesh.vertices, s.mesh.vertices);
  EXPECT_EQ(t.mesh.faces, s.mesh.faces);
  EXPECT_EQ(t.texture.rgb, s.texture.rgb);
  ASSERT_EQ(t.texture.corner_uv.size(), s.texture.corner_uv.size());
  for (size_t f = 0; f < s.mesh.faces.size(); ++f)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(t.texture.corner_uv[f][k], s.texture.corner_uv[f][k]);
  // A glb whose texture is not a PNG is refused in one line.
  std::string g(bytes.begin(), bytes.end());
  const size_t at = g.find("image/png");
  ASSERT_NE(at, std::string::npos);
  g.replace(at, 9, "image/gif");
  test::write_text(dir + "/gif.glb", g);
  std::string out;
  EXPECT_EQ(test::run(kBin + " -q pose --skin " + dir + "/gif.glb --out " + dir + "/x.ply", &out), 1);
  EXPECT_NE(out.find("must be a PNG"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/x.ply"));
}

// The thesis's blend: the colour is (1 − w) × the lit white surface + w × the texture.
TEST(Texture, PicturesBlendShadingAndTextureByTheWeight) {
  const Mesh quad{{{0, 0, 0}, {10, 0, 0}, {10, 10, 0}, {0, 10, 0}}, {{{0, 1, 2}}, {{0, 2, 3}}}};
  TextureMap red;
  red.size = 64;
  red.rgb.assign(64 * 64 * 3, 0);
  for (size_t i = 0; i < red.rgb.size(); i += 3) red.rgb[i] = 200;
  red.corner_uv = {{Eigen::Vector2f(0.1f, 0.1f), {0.9f, 0.1f}, {0.9f, 0.9f}}, {Eigen::Vector2f(0.1f, 0.1f), {0.9f, 0.9f}, {0.1f, 0.9f}}};
  RenderOptions ro;
  ro.width = ro.height = 64;
  ro.texture = &red;
  const auto centre = [&](float w) {
    ro.texture_weight = w;
    const Rgb8Image img = decode_rgb8_png(render_mesh_png({&quad}, ro), "picture");
    const std::uint8_t* c = &img.rgb[(32 * 64 + 32) * 3];
    return Eigen::Vector3d(c[0], c[1], c[2]);
  };
  const Eigen::Vector3d textured = centre(1.0f), shaded = centre(0.0f), thesis = centre(0.7f);
  EXPECT_NEAR(textured.x(), 200, 3);
  EXPECT_LT(textured.y(), 3);
  EXPECT_NEAR(shaded.x(), shaded.y(), 3);  // white light on a white surface: grey
  EXPECT_GT(shaded.y(), 100);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(thesis(c), 0.3 * shaded(c) + 0.7 * textured(c), 3) << c;
}

TEST(Texture, BadPhotosAreRefusedInOneLineAndNothingIsWritten) {
  const std::string dir = test::temp_dir("texture-bad");
  const std::string base = kBin + " -q run --back " + kFix + "back --palm " + kFix + "palm --rig " + kFix + "rig.json --out " + dir + "/out";
  std::string out;
  auto refused = [&](const std::string& args, const std::string& says) {
    EXPECT_EQ(test::run(base + " " + args, &out), 1) << args;
    EXPECT_NE(out.find(says), std::string::npos) << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
    EXPECT_FALSE(fs::exists(dir + "/out"));
  };
  refused("--back-photo " + kFix + "back.png", "must be 8-bit RGB");  // the range image
  write_file_atomic(dir + "/small.png", encode_rgb8_png(10, 10, std::vector<std::uint8_t>(300, 128)));
  refused("--palm-photo " + dir + "/small.png", "small.png: the photo is 10 x 10 pixels; its scan's grid is 512 x 512");
  refused("--back-photo " + dir + "/missing.png", "missing.png");
  test::write_text(dir + "/bad.json", R"({"format": "handskin-pipeline/1", "texture": {"size": 10}})");
  EXPECT_EQ(test::run(base + " --pipeline " + dir + "/bad.json", &out), 1);
  EXPECT_NE(out.find("texture.size"), std::string::npos) << out;
}

TEST(Texture, WithoutPhotosTheRunSaysSoAndTheSkinIsPlain) {
  const std::string dir = test::temp_dir("texture-none");
  for (const char* f : {"back.png", "back.json", "palm.png", "palm.json"}) fs::copy_file(kFix + f, dir + "/" + f);
  fs::copy_file(kFix + "back.photo.png", dir + "/back.photo.png");  // one photo alone is not enough
  std::string out;
  ASSERT_EQ(test::run(kBin + " run --back " + dir + "/back --palm " + dir + "/palm --rig " + kFix + "rig.json --out " + dir + "/out", &out), 0) << out;
  EXPECT_NE(out.find("no texture: " + dir + "/palm.photo.png not found"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/out/texture.png"));
  EXPECT_TRUE(read_skin_glb(dir + "/out/skin.glb").texture.empty());
  // synth scan --no-photos writes none; by default it writes both.
  const std::string hand = dir + "/hand";
  ASSERT_EQ(test::run(kBin + " -q synth hand --out " + hand + " --no-render", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q synth scan --mesh " + hand + "/hand.ply --rig " + hand + "/hand_rig.json --out " + dir +
                          "/scan --no-render --no-photos", &out), 0) << out;
  EXPECT_FALSE(fs::exists(dir + "/scan/back.photo.png"));
}

// skin.obj carries the texture: vt per corner equal to the glb's (v flipped, as OBJ has it),
// vn per vertex, and skin.mtl whose map is texture.png beside it.
TEST(Texture, SkinObjCarriesTheTexturesCoordinatesAndMaterial) {
  const std::string run = test::default_fixture_run();
  const RiggedSkin skin = read_skin_glb(run + "/skin.glb");
  ASSERT_FALSE(skin.texture.empty());
  std::istringstream in(read_file(run + "/skin.obj"));
  std::vector<Eigen::Vector2f> vt;
  size_t vn = 0, f = 0, bad = 0;
  std::string mtllib, line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "mtllib") ls >> mtllib;
    if (key == "vn") ++vn;
    if (key == "vt") {
      float u = 0, v = 0;
      ls >> u >> v;
      vt.emplace_back(u, v);
    }
    if (key == "f") {
      for (int k = 0; k < 3; ++k) {
        std::string c;
        ls >> c;
        int a = 0, t = 0, n = 0;
        ASSERT_EQ(std::sscanf(c.c_str(), "%d/%d/%d", &a, &t, &n), 3) << line;
        ASSERT_EQ(a, skin.mesh.faces[f][k] + 1);
        ASSERT_EQ(n, a);
        const Eigen::Vector2f want = skin.texture.corner_uv[f][k];
        if ((vt.at(t - 1) - Eigen::Vector2f(want.x(), 1.0f - want.y())).norm() > 1e-5f) ++bad;
      }
      ++f;
    }
  }
  EXPECT_EQ(f, skin.mesh.faces.size());
  EXPECT_EQ(vn, skin.mesh.vertices.size());
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(mtllib, "skin.mtl");
  EXPECT_NE(read_file(run + "/skin.mtl").find("map_Kd texture.png"), std::string::npos);
  EXPECT_TRUE(std::filesystem::exists(run + "/texture.png"));
}

// The mesh pictures (render/mesh_raster.cpp): what any renderer of them must give — the
// silhouette where the projection puts it, the nearer surface in front, both sides lit alike,
// OpenGL's lighting formula for a face toward the viewer, and the joints' dots on top.
TEST(Texture, MeshPicturesCoverOccludeAndLightAsOpenGL) {
  const auto square = [](double z, bool flipped) {
    Mesh m{{{0, 0, z}, {10, 0, z}, {10, 10, z}, {0, 10, z}}, {{{0, 1, 2}}, {{0, 2, 3}}}};
    if (flipped)
      for (auto& f : m.faces) std::swap(f[1], f[2]);
    return m;
  };
  RenderOptions ro;
  ro.width = ro.height = 100;
  const auto picture = [&](const std::vector<const Mesh*>& meshes) { return decode_rgb8_png(render_mesh_png(meshes, ro), "picture"); };
  const auto pixel = [](const Rgb8Image& img, int x, int y) {
    const std::uint8_t* c = &img.rgb[(static_cast<size_t>(y) * img.width + x) * 3];
    return Eigen::Vector3i(c[0], c[1], c[2]);
  };
  const Eigen::Vector3i background(raster::kBackground[0], raster::kBackground[1], raster::kBackground[2]);
  // A 10 mm square facing the viewer fills 92 % of the frame, centred: the corners' 4 % are
  // background, its middle the skin tone lit as OpenGL lights a normal along +Z.
  const Mesh front = square(0, false), back = square(0, true);
  const Rgb8Image a = picture({&front});
  EXPECT_EQ(pixel(a, 1, 1), background);
  EXPECT_EQ(pixel(a, 98, 98), background);
  const Eigen::Vector3d lit = raster::Lights().shade(Eigen::Vector3d::UnitZ(), ro.colour);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(pixel(a, 50, 50)[ch], std::lround(lit[ch] * 255), 1) << ch;
  size_t covered = 0;
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x) covered += pixel(a, x, y) != background;
  EXPECT_NEAR(static_cast<double>(covered), 92.0 * 92.0, 2 * 92.0) << "the square's silhouette";
  // One flat colour inside: no crack where the two triangles meet along the diagonal.
  for (int y = 6; y < 94; ++y)
    for (int x = 6; x < 94; ++x) ASSERT_EQ(pixel(a, x, y), pixel(a, 50, 50)) << x << " " << y;
  // Its back (the faces wound the other way) is lit alike: two-sided lighting.
  EXPECT_EQ(picture({&back}).rgb, a.rgb);
  // A smaller square tilted 40° toward the key light, nearer everywhere, covers the larger
  // one's middle in either drawing order (the depth test), lit as its own normal says.
  const double t = 40 * M_PI / 180;
  const Mesh tilted{{{2.5, 2.5, 1}, {7.5, 2.5, 1}, {7.5, 2.5 + 5 * std::cos(t), 1 + 5 * std::sin(t)}, {2.5, 2.5 + 5 * std::cos(t), 1 + 5 * std::sin(t)}},
                    {{{0, 1, 2}}, {{0, 2, 3}}}};
  const Rgb8Image near_last = picture({&front, &tilted}), near_first = picture({&tilted, &front});
  EXPECT_EQ(near_last.rgb, near_first.rgb);
  const Eigen::Vector3d tilted_lit = raster::Lights().shade(Eigen::Vector3d(0, -std::sin(t), std::cos(t)), ro.colour);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(pixel(near_last, 50, 45)[ch], std::lround(tilted_lit[ch] * 255), 1) << ch;
    EXPECT_NEAR(pixel(near_last, 15, 85)[ch], std::lround(lit[ch] * 255), 1) << ch;
  }
  EXPECT_NE(pixel(near_last, 50, 45), pixel(near_last, 15, 85));
  // Joints drawn as red dots over the surface.
  ro.points = {{5, 5, -100}};
  const Rgb8Image dotted = picture({&front});
  EXPECT_EQ(pixel(dotted, 50, 50), Eigen::Vector3i(raster::kDotColour[0], raster::kDotColour[1], raster::kDotColour[2]));
}

// A colour's byte (raster::byte_of, inline) is std::lround's of it × 255 for every value,
// the halves and the doubles just below them among them.
TEST(Texture, ColourBytesAreRoundedAsLround) {
  std::vector<double> v = {0, 1, -0.5, 2, std::nan(""), 0.5 / 255, 254.5 / 255, 1e-300};
  for (int k = 0; k <= 255; ++k)
    for (const double x : {k + 0.5, std::nextafter(k + 0.5, 0.0), std::nextafter(k + 0.5, 1e9), k + 0.0,
                           std::nextafter(k + 0.0, 0.0)})
      v.push_back(x / 255), v.push_back(std::nextafter(x / 255, 0.0)), v.push_back(std::nextafter(x / 255, 2.0));
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.1, 1.1);
  for (int k = 0; k < 200000; ++k) v.push_back(u(rng));
  for (const double x : v)
    ASSERT_EQ(raster::byte_of(x), static_cast<std::uint8_t>(std::lround(std::clamp(x, 0.0, 1.0) * 255))) << x;
}

// The mesh pictures are drawn in two passes (the nearest face of each pixel, then its colour)
// over each row's span of each face (render/mesh_raster.cpp); every byte must be what drawing
// every fragment in turn gives: the reference below, written out plainly (the renderer before
// 2026-11-30). Random soups of overlapping triangles, some facing away, some at equal depths
// (ties: the first drawn kept), edges shared, slivers, a texture, two meshes.
TEST(Texture, MeshPicturesInTwoPassesAreThoseOfEveryFragmentInTurn) {
  struct Edge {  // as mesh_raster.cpp's
    double ux, uy, dx, dy, sign;
    Edge(const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
      const bool swap = q.x() < p.x() || (q.x() == p.x() && q.y() < p.y());
      const Eigen::Vector3d& a = swap ? q : p;
      const Eigen::Vector3d& b = swap ? p : q;
      ux = a.x(), uy = a.y(), dx = b.x() - a.x(), dy = b.y() - a.y(), sign = swap ? -1.0 : 1.0;
    }
    double operator()(double x, double y) const { return sign * (dx * (y - uy) - dy * (x - ux)); }
  };
  const auto bilinear = [](const TextureMap& t, double u, double v) {
    const int S = t.size;
    const double x = u * S - 0.5, y = v * S - 0.5, fx = std::floor(x), fy = std::floor(y), ax = x - fx, ay = y - fy;
    const int x0 = std::clamp(static_cast<int>(fx), 0, S - 1), x1 = std::clamp(static_cast<int>(fx) + 1, 0, S - 1);
    const int y0 = std::clamp(static_cast<int>(fy), 0, S - 1), y1 = std::clamp(static_cast<int>(fy) + 1, 0, S - 1);
    const std::uint8_t* r0 = &t.rgb[static_cast<size_t>(y0) * S * 3];
    const std::uint8_t* r1 = &t.rgb[static_cast<size_t>(y1) * S * 3];
    Eigen::Vector3d c;
    for (int ch = 0; ch < 3; ++ch)
      c[ch] = ((1 - ay) * ((1 - ax) * r0[3 * x0 + ch] + ax * r0[3 * x1 + ch]) + ay * ((1 - ax) * r1[3 * x0 + ch] + ax * r1[3 * x1 + ch])) / 255.0;
    return c;
  };
  const auto reference = [&](const std::vector<const Mesh*>& meshes, const RenderOptions& o) {
    const std::vector<Eigen::Vector3d> all = [&] {
      std::vector<Eigen::Vector3d> a;
      for (const Mesh* m : meshes) a.insert(a.end(), m->vertices.begin(), m->vertices.end());
      return a;
    }();
    const raster::Framing f = raster::frame(o, all);
    constexpr int S = raster::kSupersample;
    const int W = o.width * S, H = o.height * S;
    std::vector<std::uint8_t> rgba;
    raster::clear_to_background(&rgba, static_cast<size_t>(W) * H);
    std::vector<float> depth(static_cast<size_t>(W) * H, -std::numeric_limits<float>::infinity());
    const raster::Lights lights;
    for (size_t m = 0; m < meshes.size(); ++m) {
      const Mesh& mesh = *meshes[m];
      const TextureMap* tex = m == 0 && o.texture && !o.texture->empty() ? o.texture : nullptr;
      const Eigen::Vector3f material = tex ? Eigen::Vector3f::Constant(0.92f) : o.colour;
      const double w_tex = tex ? o.texture_weight : 0.0;
      const std::vector<Eigen::Vector3d> normal = shading_normals(mesh);
      std::vector<Eigen::Vector3d> win(mesh.vertices.size());
      std::vector<std::array<Eigen::Vector3d, 2>> lit(mesh.vertices.size());
      for (size_t v = 0; v < win.size(); ++v) {
        const Eigen::Vector3d q = o.view * mesh.vertices[v];
        win[v] << f.window(q), q.z();
        Eigen::Vector3d n = o.view * normal[v];
        if (n.squaredNorm() > 0) n.normalize();
        else n = Eigen::Vector3d::UnitZ();
        lit[v][0] = lights.shade(n, material), lit[v][1] = lights.shade(-n, material);
      }
      for (size_t fi = 0; fi < mesh.faces.size(); ++fi) {
        const auto& t = mesh.faces[fi];
        const Eigen::Vector3d &a = win[t[0]], &b = win[t[1]], &c = win[t[2]];
        const double area = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
        if (!(std::abs(area) > 1e-12)) continue;
        const int side = area < 0 ? 0 : 1;
        const double s = area < 0 ? -1.0 : 1.0;
        const auto owns = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
          const double dx = s * (q.x() - p.x()), dy = s * (q.y() - p.y());
          return dy < 0 || (dy == 0 && dx > 0);
        };
        const bool own0 = owns(b, c), own1 = owns(c, a), own2 = owns(a, b);
        const Edge E0(b, c), E1(c, a), E2(a, b);
        for (int y = 0; y < H; ++y)  // every pixel of the picture: no bounding box to trust
          for (int x = 0; x < W; ++x) {
            const double px = x + 0.5, py = y + 0.5;
            const double e0 = s * E0(px, py), e1 = s * E1(px, py), e2 = s * E2(px, py);
            if (e0 < 0 || e1 < 0 || e2 < 0) continue;
            if ((e0 == 0 && !own0) || (e1 == 0 && !own1) || (e2 == 0 && !own2)) continue;
            const double sum = e0 + e1 + e2;
            if (!(sum > 0)) continue;
            const double l0 = e0 / sum, l1 = e1 / sum, l2 = e2 / sum;
            const size_t at = static_cast<size_t>(y) * W + x;
            const float z = static_cast<float>(l0 * a.z() + l1 * b.z() + l2 * c.z());
            if (!(z > depth[at])) continue;
            depth[at] = z;
            Eigen::Vector3d col = l0 * lit[t[0]][side] + l1 * lit[t[1]][side] + l2 * lit[t[2]][side];
            if (tex) {
              const auto& uv = tex->corner_uv[fi];
              col = w_tex * bilinear(*tex, l0 * uv[0].x() + l1 * uv[1].x() + l2 * uv[2].x(),
                                     l0 * uv[0].y() + l1 * uv[1].y() + l2 * uv[2].y()) +
                    (1 - w_tex) * col;
            }
            for (int ch = 0; ch < 3; ++ch) rgba[4 * at + ch] = raster::byte_of(col[ch]);
          }
      }
    }
    raster::draw_dots(o, f, W, H, &rgba);
    return raster::downsample_png(rgba, o.width, o.height);
  };
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-20, 20), z(-5, 5);
  const auto soup = [&](int triangles, bool snap) {
    Mesh m;
    for (int k = 0; k < triangles; ++k) {
      const int base = static_cast<int>(m.vertices.size());
      // Snapped to a coarse grid, corners land on pixel centres and edges pass through them,
      // and many triangles lie at one depth (ties).
      const auto corner = [&] {
        Eigen::Vector3d p(u(rng), u(rng), z(rng));
        if (snap) p = (p * 0.5).array().round() * 2.0, p.z() = std::round(p.z() / 5) * 5;
        return p;
      };
      const Eigen::Vector3d a = corner(), b = corner();
      m.vertices.push_back(a), m.vertices.push_back(b);
      m.vertices.push_back(k % 9 == 0 ? Eigen::Vector3d(a + 1e-3 * (b - a)) : corner());  // a sliver now and then
      m.faces.push_back({base, base + 1, base + 2});
      if (k % 4 == 0) {  // a neighbour across its first edge, wound the other way round it
        m.vertices.push_back(corner());
        m.faces.push_back({base + 1, base, base + 3});
      }
    }
    return m;
  };
  TextureMap tex;
  tex.size = 16;
  for (int k = 0; k < 16 * 16 * 3; ++k) tex.rgb.push_back(static_cast<std::uint8_t>((k * 37) % 256));
  int compared = 0;
  for (const bool snap : {false, true})
    for (const bool textured : {false, true}) {
      const Mesh one = soup(60, snap), two = soup(25, !snap);
      for (size_t f = 0; f < one.faces.size(); ++f)
        tex.corner_uv.push_back({Eigen::Vector2f(0.1f, 0.2f), Eigen::Vector2f(0.9f, 0.3f * (f % 3)), Eigen::Vector2f(0.5f, 0.95f)});
      RenderOptions o;
      o.width = 61, o.height = 47;  // odd sizes: a last row and column of their own
      o.view = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
      o.points = {{0, 0, 0}};
      if (textured) o.texture = &tex, o.texture_weight = 0.6;
      for (const std::vector<const Mesh*>& meshes : {std::vector<const Mesh*>{&one}, std::vector<const Mesh*>{&one, &two}}) {
        const Rgb8Image want = decode_rgb8_png(reference(meshes, o), "every fragment");
        const Rgb8Image got = decode_rgb8_png(render_mesh_png(meshes, o), "two passes");
        ASSERT_EQ(got.rgb.size(), want.rgb.size());
        size_t differ = 0, drawn = 0;
        for (size_t k = 0; k < want.rgb.size(); ++k) differ += got.rgb[k] != want.rgb[k];
        for (size_t k = 0; k < want.rgb.size(); k += 3) drawn += want.rgb[k] != raster::kBackground[0];
        EXPECT_EQ(differ, 0u) << "snapped " << snap << ", textured " << textured << ", meshes " << meshes.size();
        EXPECT_GT(drawn, want.rgb.size() / 3 / 4) << "the soup covers a good part of the picture";
        ++compared;
      }
      tex.corner_uv.clear();
    }
  EXPECT_EQ(compared, 8);
}

// The splat pictures (render/splats.cpp) are drawn a band of rows at a time to keep their
// memory small; every pixel must be what one whole-picture buffer gives: splats and dots
// across the bands' borders, a last band shorter than the others, ties in depth (the first
// drawn kept). The reference below is the one-buffer drawing, written out plainly.
TEST(Texture, SplatPicturesDrawnByBandsAreThoseOfOneBuffer) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Vector3d> p, n;
  std::vector<Eigen::Vector3f> c;
  for (int k = 0; k < 4000; ++k) {
    p.emplace_back(40 * u(rng), 30 * u(rng), k % 5 == 0 ? 0.0 : 3 * u(rng));  // every fifth at z = 0: ties
    n.push_back(k % 7 == 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(u(rng), u(rng), 1).normalized());
    c.emplace_back(0.5f + 0.4f * static_cast<float>(u(rng)), 0.6f, 0.5f + 0.3f * static_cast<float>(u(rng)));
  }
  RenderOptions o;
  o.view = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (int y = -30; y <= 30; y += 3) o.points.emplace_back(0.7 * y, y, 0);  // dots on many rows
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{160, 101}, {90, 32}, {300, 250}}) {
    o.width = w, o.height = h;
    const raster::Framing f = raster::frame(o, p);
    constexpr int S = raster::kSupersample;
    const int W = w * S, H = h * S;
    std::vector<std::uint8_t> rgba;
    raster::clear_to_background(&rgba, static_cast<size_t>(W) * H);
    std::vector<double> depth(static_cast<size_t>(W) * H, -std::numeric_limits<double>::infinity());
    const double diameter = std::max(1.0, std::max(3.0, 1.0 * f.scale) * S);
    const raster::Lights lights;
    for (size_t k = 0; k < p.size(); ++k) {
      const Eigen::Vector3d q = o.view * p[k];
      const Eigen::Vector3d nn = n[k].squaredNorm() > 0.5 ? Eigen::Vector3d((o.view * n[k]).normalized()) : Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d col = lights.shade(nn, c[k]);
      const Eigen::Vector2d win = f.window(q);
      raster::disc(win.x(), win.y(), diameter, W, H, [&](size_t at) {
        if (!(q.z() > depth[at])) return;
        depth[at] = q.z();
        for (int ch = 0; ch < 3; ++ch) rgba[4 * at + ch] = raster::byte_of(col[ch]);
      });
    }
    raster::draw_dots(o, f, W, H, &rgba);
    const Rgb8Image want = decode_rgb8_png(raster::downsample_png(rgba, w, h), "one buffer");
    const Rgb8Image got = decode_rgb8_png(render_points_png(p, n, c, o), "by bands");
    ASSERT_EQ(got.width, w);
    ASSERT_EQ(got.height, h);
    size_t differ = 0;
    for (size_t k = 0; k < want.rgb.size(); ++k) differ += got.rgb[k] != want.rgb[k];
    EXPECT_EQ(differ, 0u) << w << " x " << h;
  }
}
