// The skin's texture from the scans' photos. The bake (rasterising each chart's faces in
// texture space and sampling the photos per texel) is written here: it is a few loops over
// plain arrays, and none of the project's libraries bakes a texture from projected photos
// (OSMesa could rasterise the charts, but the per-texel visibility and blending would then
// live in shaders that fixed-function GL does not have). Visibility rays use CGAL's AABB tree.
#include "texture/texture.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "mesh/triangle_tree.hpp"
#include "mesh/mesh.hpp"

namespace handskin {

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr int kPadTexels = 6;          // around each chart, so filtering never reaches the background
constexpr int kUnseenBlock = 16;       // texels of the unseen faces' flat colour block
// Skin within this of a marker's outline (seen along a view) and below its top plus the same
// is hidden by it: round a marker the skin is interpolated over the marker's hole and may
// stand a little proud of the true surface, which the photo shows as the white marker.
constexpr double kMarkerMarginMm = 2.0;
// A photo pixel shows a skin point when the scan measured a height within this of the point's
// there: the skin is within ~0.3 mm of the scan, and a steep flank rises ~1.5 mm across a pixel.
constexpr double kPhotoDepthToleranceMm = 2.0;

double smoothstep(double a, double b, double x) {
  const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// One camera: the palm scan's (the model frame) or the back scan's, through the registration.
struct View {
  const ScanPhoto* photo;
  Eigen::Isometry3d from_palm;  // model (palm) frame -> this scan's frame
  Eigen::Vector3d up;           // toward the camera, model frame
  std::vector<Eigen::Vector3d> markers;  // this scan's frame
};

// Bilinear sample of the photo at a point of its scan's frame, over the pixels that show it
// (the range image measured the point's height there). False when none does.
bool sample(const ScanPhoto& ph, const Eigen::Vector3d& q, Eigen::Vector3d* colour) {
  const ScanMeta& g = ph.scan.meta;
  const double fi = (q.x() - g.x_origin_mm) / g.x_step_mm, fj = (q.y() - g.y_origin_mm) / g.y_step_mm;
  const int i0 = static_cast<int>(std::floor(fi)), j0 = static_cast<int>(std::floor(fj));
  const double ti = fi - i0, tj = fj - j0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double wsum = 0;
  for (int di = 0; di < 2; ++di)
    for (int dj = 0; dj < 2; ++dj) {
      const int i = i0 + di, j = j0 + dj;
      if (i < 0 || j < 0 || i >= g.scanlines || j >= g.points) continue;
      const size_t idx = static_cast<size_t>(i) * g.points + j;
      const std::uint16_t v = ph.scan.values[idx];
      if (v == 0 || std::abs(g.z_origin_mm + v * g.z_step_mm - q.z()) > kPhotoDepthToleranceMm) continue;
      const double w = (di ? ti : 1 - ti) * (dj ? tj : 1 - tj) + 1e-6;
      const std::uint8_t* c = &ph.image.rgb[idx * 3];
      sum += w * Eigen::Vector3d(c[0], c[1], c[2]);
      wsum += w;
    }
  if (wsum <= 0) return false;
  *colour = sum / wsum;
  return true;
}

bool behind_marker(const View& v, const Eigen::Vector3d& q, double r) {
  for (const auto& c : v.markers)
    if (c.z() + r + kMarkerMarginMm > q.z() && (c.head<2>() - q.head<2>()).norm() < r + kMarkerMarginMm) return true;
  return false;
}

}  // namespace

bool TextureOptions::IsValid(std::string* error) const {
  if (size < 64 || size > 8192) return *error = "texture size must be in [64, 8192] texels", false;
  if (!(blend_deg > 0 && blend_deg <= 60)) return *error = "texture blend must be in (0, 60] degrees", false;
  return true;
}

ScanPhoto load_scan_photo(const std::string& file, const RangeScan& scan) {
  ScanPhoto ph;
  ph.image = decode_rgb8_png(read_file(file), file);
  ph.scan = scan;
  const ScanMeta& grid = scan.meta;
  if (ph.image.width != grid.points || ph.image.height != grid.scanlines)
    throw InputError(file, "the photo is " + std::to_string(ph.image.width) + " x " + std::to_string(ph.image.height) +
                               " pixels; its scan's grid is " + std::to_string(grid.points) + " x " +
                               std::to_string(grid.scanlines) + " (points x scanlines)");
  return ph;
}

namespace {

// x in [0, 255] rounded to the nearest byte, halves up: std::lround's bytes, inline (libm's
// lroundf for each of a 1024² atlas's 3 M channels took about a tenth of the bake's samples in
// perf). x − ⌊x⌋ is exact there (Sterbenz).
inline std::uint8_t byte_of(float x) {
  if (!(x >= 0.f && x <= 255.f)) return static_cast<std::uint8_t>(std::lround(x));  // NaN: as lround has it
  const int r = static_cast<int>(x);
  return static_cast<std::uint8_t>(r + (x - static_cast<float>(r) >= 0.5f ? 1 : 0));
}

// One bake: the skin, the two views, and the texture growing texel by texel.
struct Baker {
  Baker(const std::vector<Eigen::Vector3d>& V, const std::vector<std::array<int, 3>>& F, const ScanPhoto& back,
        const ScanPhoto& palm, const Eigen::Isometry3d& back_to_palm, const std::vector<Eigen::Vector3d>& markers,
        double marker_radius, const TextureOptions& o)
      : V(V), F(F), o(o), marker_radius(marker_radius), S(o.size), s(std::sin(o.blend_deg * kDeg)),
        colour(static_cast<size_t>(S) * S, Eigen::Vector3f::Zero()), state(static_cast<size_t>(S) * S, 0) {
    views[0] = {&palm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::UnitZ(), {}};
    views[1] = {&back, back_to_palm.inverse(), (back_to_palm.linear() * Eigen::Vector3d::UnitZ()).normalized(), {}};
    for (auto& v : views)
      for (const auto& m : markers) v.markers.push_back(v.from_palm * m);
  }

  // Vertex normals (area-weighted) and, per view, whether the camera sees the vertex: a ray
  // toward the camera that meets no other part of the skin.
  void visibility() {
    N = vertex_normals(V, F);
    const cgal::TriangleTree tree(V, F);
    for (int c = 0; c < 2; ++c) {
      seen[c].assign(V.size(), 0.0);
      const Eigen::Vector3d& up = views[c].up;
      for (size_t k = 0; k < V.size(); ++k) {
        if (N[k].dot(up) < -std::sin(o.blend_deg * kDeg)) continue;
        const Eigen::Vector3d q = V[k] + 0.3 * up + 0.05 * N[k];
        seen[c][k] = tree.tree.do_intersect(cgal::K::Ray_3(cgal::point(q), cgal::K::Vector_3(up.x(), up.y(), up.z()))) ? 0.0 : 1.0;
      }
    }

  }
  // Charts: each face goes to the camera it faces more, among those that see all its corners.
  void choose_charts() {
    chart.assign(F.size(), -1);
    for (size_t f = 0; f < F.size(); ++f) {
      const auto& t = F[f];
      const Eigen::Vector3d fn = (V[t[1]] - V[t[0]]).cross(V[t[2]] - V[t[0]]).normalized();
      double best = 0;
      for (int c = 0; c < 2; ++c) {
        const double facing = fn.dot(views[c].up);
        if (facing > best && seen[c][t[0]] > 0 && seen[c][t[1]] > 0 && seen[c][t[2]] > 0) best = facing, chart[f] = c;
      }
    }
  }
  // Each chart projected on its scan's X-Y plane; one scale for both, the long side along v.
  void lay_out_charts(SkinTexture* out) {
    for (int c = 0; c < 2; ++c) lo[c] = Eigen::Vector2d::Constant(1e18), hi[c] = -lo[c];
    for (size_t f = 0; f < F.size(); ++f)
      if (chart[f] >= 0)
        for (int k : F[f]) {
          const Eigen::Vector3d q = views[chart[f]].from_palm * V[k];
          lo[chart[f]] = lo[chart[f]].cwiseMin(q.head<2>());
          hi[chart[f]] = hi[chart[f]].cwiseMax(q.head<2>());
        }
    scale = 1e18;
    for (int c = 0; c < 2; ++c)
      if (hi[c].x() >= lo[c].x()) {
        const Eigen::Vector2d ext = (hi[c] - lo[c]).cwiseMax(1e-6);
        scale = std::min({scale, (S / 2.0 - 2 * kPadTexels) / ext.y(), (S - kUnseenBlock - 2.0 * kPadTexels) / ext.x()});
      }
    if (scale > 1e17) scale = 1;  // neither camera sees anything: only the flat block
    out->texels_per_mm = scale;
  }
  // Texture-space position of p in chart c, texels.
  Eigen::Vector2d texel_of(int c, const Eigen::Vector3d& p) const {
    const Eigen::Vector3d q = views[c].from_palm * p;
    return Eigen::Vector2d(c * S / 2.0 + kPadTexels + (q.y() - lo[c].y()) * scale, kPadTexels + (q.x() - lo[c].x()) * scale);
  
  }
  // How much each photo gives a point p with normal n, seen `vis` by each camera.
  std::array<double, 2> weights(const Eigen::Vector3d& p, const Eigen::Vector3d& n, const std::array<double, 2>& vis) const {
    std::array<double, 2> w{};
    for (int c = 0; c < 2; ++c) {
      if (vis[c] <= 0) continue;
      const Eigen::Vector3d q = views[c].from_palm * p;
      if (behind_marker(views[c], q, marker_radius)) continue;
      w[c] = vis[c] * smoothstep(-s, s, n.dot(views[c].up));
    }
    return w;
  
  }
  // Bake: per texel of each chart face, the point and normal on the skin, and the photos'
  // colours weighted by how squarely and whether each camera sees it; each face's area share.
  void bake_faces(SkinTexture* out);
  void raster_face(size_t f, const std::array<Eigen::Vector2d, 3>& uv);
  // Fill: chart texels no photo coloured take their coloured neighbours' mean, pass after
  // pass (a marker's shadow closes from its rim); then kPadTexels passes pad the charts.
  void fill(SkinTexture* out);

  const std::vector<Eigen::Vector3d>& V;
  const std::vector<std::array<int, 3>>& F;
  const TextureOptions& o;
  const double marker_radius;
  const int S;
  const double s;  ///< sin of the blend angle
  std::array<View, 2> views;  ///< 0: palm, 1: back
  std::vector<Eigen::Vector3d> N;
  std::array<std::vector<double>, 2> seen;
  std::vector<int> chart;
  std::array<Eigen::Vector2d, 2> lo, hi;
  double scale = 1e18;
  std::vector<Eigen::Vector3f> colour;
  std::vector<std::uint8_t> state;  ///< 0 outside, 1 chart but unseen, 2 coloured
};

void Baker::bake_faces(SkinTexture* out) {
  out->map.corner_uv.resize(F.size());
  double area[4] = {0, 0, 0, 0};  // palm only, back only, blended, unseen
  const Eigen::Vector2f unseen_uv((kUnseenBlock / 2.0f) / S, (S - kUnseenBlock / 2.0f) / S);
  for (size_t f = 0; f < F.size(); ++f) {
    const auto& t = F[f];
    const double a3 = 0.5 * (V[t[1]] - V[t[0]]).cross(V[t[2]] - V[t[0]]).norm();
    const int c = chart[f];
    {  // the face's share by its centroid
      const Eigen::Vector3d p = (V[t[0]] + V[t[1]] + V[t[2]]) / 3.0, n = (N[t[0]] + N[t[1]] + N[t[2]]).normalized();
      std::array<double, 2> vis{};
      for (int v = 0; v < 2; ++v) vis[v] = (seen[v][t[0]] + seen[v][t[1]] + seen[v][t[2]]) / 3.0;
      const auto w = c < 0 ? std::array<double, 2>{} : weights(p, n, vis);
      const double sum = w[0] + w[1];
      area[sum <= 1e-3 ? 3 : w[1] / sum < 0.02 ? 0 : w[0] / sum < 0.02 ? 1 : 2] += a3;
    }
    if (c < 0) {
      ++out->unseen_faces;
      out->map.corner_uv[f] = {unseen_uv, unseen_uv, unseen_uv};
      continue;
    }
    ++(c == 0 ? out->palm_chart_faces : out->back_chart_faces);
    std::array<Eigen::Vector2d, 3> uv;
    for (int k = 0; k < 3; ++k) {
      uv[k] = texel_of(c, V[t[k]]);
      out->map.corner_uv[f][k] = (uv[k] / S).cast<float>();
    }
    const double den = (uv[1] - uv[0]).x() * (uv[2] - uv[0]).y() - (uv[1] - uv[0]).y() * (uv[2] - uv[0]).x();
    if (std::abs(den) < 1e-9) continue;  // a sliver seen edge-on: its texels come from the neighbours
    raster_face(f, uv);
  }
  double total = area[0] + area[1] + area[2] + area[3];
  total = total > 0 ? total : 1;
  out->palm_only = area[0] / total, out->back_only = area[1] / total, out->blended = area[2] / total, out->unseen = area[3] / total;
}

void Baker::raster_face(size_t f, const std::array<Eigen::Vector2d, 3>& uv) {
  const auto& t = F[f];
  const double den = (uv[1] - uv[0]).x() * (uv[2] - uv[0]).y() - (uv[1] - uv[0]).y() * (uv[2] - uv[0]).x();
  const Eigen::Vector2d bl = uv[0].cwiseMin(uv[1]).cwiseMin(uv[2]), bh = uv[0].cwiseMax(uv[1]).cwiseMax(uv[2]);
  for (int y = std::max(0, static_cast<int>(bl.y()) - 1); y <= std::min(S - 1, static_cast<int>(bh.y()) + 1); ++y)
    for (int x = std::max(0, static_cast<int>(bl.x()) - 1); x <= std::min(S - 1, static_cast<int>(bh.x()) + 1); ++x) {
      const Eigen::Vector2d q(x + 0.5, y + 0.5);
      const double b1 = ((q - uv[0]).x() * (uv[2] - uv[0]).y() - (q - uv[0]).y() * (uv[2] - uv[0]).x()) / den;
      const double b2 = ((uv[1] - uv[0]).x() * (q - uv[0]).y() - (uv[1] - uv[0]).y() * (q - uv[0]).x()) / den;
      const double b0 = 1 - b1 - b2;
      if (b0 < -0.02 || b1 < -0.02 || b2 < -0.02) continue;
      const size_t idx = static_cast<size_t>(y) * S + x;
      if (state[idx] == 2) continue;
      const Eigen::Vector3d p = b0 * V[t[0]] + b1 * V[t[1]] + b2 * V[t[2]];
      const Eigen::Vector3d n = (b0 * N[t[0]] + b1 * N[t[1]] + b2 * N[t[2]]).normalized();
      std::array<double, 2> vis{};
      for (int v = 0; v < 2; ++v) vis[v] = b0 * seen[v][t[0]] + b1 * seen[v][t[1]] + b2 * seen[v][t[2]];
      const auto w = weights(p, n, vis);
      if (w[0] + w[1] <= 1e-3) {
        state[idx] = 1;
        continue;
      }
      Eigen::Vector3d col = Eigen::Vector3d::Zero(), c;
      double wsum = 0;
      for (int v = 0; v < 2; ++v)
        if (w[v] > 0 && sample(*views[v].photo, views[v].from_palm * p, &c)) col += w[v] * c, wsum += w[v];
      if (wsum <= 1e-3) {
        state[idx] = 1;
        continue;
      }
      colour[idx] = (col / wsum).cast<float>();
      state[idx] = 2;
    }
}

void Baker::fill(SkinTexture* out) {
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();
  size_t coloured = 0;
  for (size_t i = 0; i < state.size(); ++i)
    if (state[i] == 2) mean += colour[i], ++coloured;
  mean = coloured ? Eigen::Vector3f(mean / static_cast<float>(coloured)) : Eigen::Vector3f(200, 160, 140);
  std::vector<size_t> pending;
  for (size_t i = 0; i < state.size(); ++i)
    if (state[i] == 1) pending.push_back(i);
  const auto grow = [&](std::vector<size_t>& todo) {
    std::vector<std::pair<size_t, Eigen::Vector3f>> done;
    std::vector<size_t> left;
    for (size_t i : todo) {
      const int x = static_cast<int>(i % S), y = static_cast<int>(i / S);
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx || dy) && xx >= 0 && yy >= 0 && xx < S && yy < S && state[static_cast<size_t>(yy) * S + xx] == 2)
            sum += colour[static_cast<size_t>(yy) * S + xx], ++n;
        }
      if (n) done.emplace_back(i, sum / static_cast<float>(n));
      else left.push_back(i);
    }
    for (const auto& [i, c] : done) colour[i] = c, state[i] = 2;
    todo.swap(left);
    return !done.empty();
  };
  while (!pending.empty() && grow(pending)) {
  }
  for (size_t i : pending) colour[i] = mean, state[i] = 2;  // a chart island no photo reached
  // The padding: kPadTexels passes, each colouring every texel beside a coloured one from the
  // colours at the pass's start (as grow). A texel can first qualify in the pass after one of
  // its neighbours was coloured, so each pass visits only the neighbours of the texels the
  // last one coloured, not the whole texture's uncoloured texels (the bake 0.09 → 0.05 s at 1024²).
  std::vector<char> queued(state.size(), 0);
  std::vector<size_t> frontier;
  const auto queue_neighbours = [&](size_t i) {
    const int x = static_cast<int>(i % S), y = static_cast<int>(i / S);
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (!(dx || dy) || xx < 0 || yy < 0 || xx >= S || yy >= S) continue;
        const size_t j = static_cast<size_t>(yy) * S + xx;
        if (state[j] != 2 && !queued[j]) queued[j] = 1, frontier.push_back(j);
      }
  };
  for (size_t i = 0; i < state.size(); ++i)
    if (state[i] == 2) queue_neighbours(i);
  for (int pass = 0; pass < kPadTexels && !frontier.empty(); ++pass) {
    std::sort(frontier.begin(), frontier.end());
    std::vector<size_t> todo;
    todo.swap(frontier);
    for (size_t i : todo) queued[i] = 0;
    std::vector<size_t> left = todo;  // every one has a coloured neighbour: grow colours them all
    grow(left);
    for (size_t i : todo)
      if (state[i] == 2) queue_neighbours(i);
  }
  out->map.size = S;
  out->map.rgb.resize(static_cast<size_t>(S) * S * 3);
  for (size_t i = 0; i < state.size(); ++i) {
    const int x = static_cast<int>(i % S), y = static_cast<int>(i / S);
    const bool block = x < kUnseenBlock && y >= S - kUnseenBlock;
    const Eigen::Vector3f c = state[i] == 2 && !block ? colour[i] : mean;
    for (int ch = 0; ch < 3; ++ch) out->map.rgb[i * 3 + ch] = byte_of(std::clamp(c[ch], 0.f, 255.f));
  }
}

}  // namespace

SkinTexture bake_skin_texture(const std::vector<Eigen::Vector3d>& V, const std::vector<std::array<int, 3>>& F,
                              const ScanPhoto& back, const ScanPhoto& palm, const Eigen::Isometry3d& back_to_palm,
                              const std::vector<Eigen::Vector3d>& markers, double marker_radius, const TextureOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string err;
  if (!o.IsValid(&err)) throw InputError("texture options", err);
  HS_CHECK(!V.empty() && !F.empty(), "no skin to texture");
  SkinTexture out;
  Baker b(V, F, back, palm, back_to_palm, markers, marker_radius, o);
  b.visibility();
  b.choose_charts();
  b.lay_out_charts(&out);
  b.bake_faces(&out);
  b.fill(&out);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace handskin
