// Meshes drawn on the CPU: triangles rasterised with a depth test, lit per vertex with OpenGL's
// fixed-function formula and interpolated (Gouraud), both sides lit, an optional texture
// blended with the lit surface as the thesis blended photo and shading, 2 × supersampled and
// box-filtered as every picture (raster.hpp).
//
// Written here rather than drawn by Mesa (gl_render.cpp, which still draws the skeletons): a
// run draws seven mesh pictures of ~8 000 triangles, and Mesa's llvmpipe cost more around them
// than in them — loading Mesa and LLVM (~0.1 s of CPU and ~90 000 symbol relocations a
// process), an OpenGL context per thread with its shaders compiled (~20 ms), the texture
// uploaded per picture — skin.png and the six posed pictures took ~0.28 s of CPU besides the
// posing. Scan conversion of a triangle with a depth test is a few dozen lines, with no Mesa to
// load, and the same bytes on any machine (no driver in between). Two passes (the nearest
// face of each pixel, then one colour per pixel) over each row's span of a face:
// BM_RenderSkinTextured1024 145 → 117 ms, BM_RenderSkin1024 102 → 84 ms (medians of 5), the
// same bytes as drawing every fragment in turn (test MeshPicturesInTwoPassesAreThoseOfEveryFragmentInTurn).
#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <limits>

#include "core/errors.hpp"
#include "render/preview.hpp"
#include "render/raster.hpp"

namespace handskin {

namespace {

// The texture's colour at (u, v), bilinear between texel centres and clamped to the edge (as
// OpenGL's GL_LINEAR with GL_CLAMP_TO_EDGE); row 0 of the image is v = 0.
Eigen::Vector3d sample_bilinear(const TextureMap& t, double u, double v) {
  const int S = t.size;
  const double x = u * S - 0.5, y = v * S - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const double ax = x - fx, ay = y - fy;
  const int x0 = std::clamp(static_cast<int>(fx), 0, S - 1), x1 = std::clamp(static_cast<int>(fx) + 1, 0, S - 1);
  const int y0 = std::clamp(static_cast<int>(fy), 0, S - 1), y1 = std::clamp(static_cast<int>(fy) + 1, 0, S - 1);
  const std::uint8_t* r0 = &t.rgb[static_cast<size_t>(y0) * S * 3];
  const std::uint8_t* r1 = &t.rgb[static_cast<size_t>(y1) * S * 3];
  Eigen::Vector3d c;
  for (int ch = 0; ch < 3; ++ch)
    c[ch] = ((1 - ay) * ((1 - ax) * r0[3 * x0 + ch] + ax * r0[3 * x1 + ch]) + ay * ((1 - ax) * r1[3 * x0 + ch] + ax * r1[3 * x1 + ch])) /
            255.0;
  return c;
}

// The line p → q as (q − p) × (x − p, y − p), positive on one side of it. Made from the
// lower endpoint and negated for the other direction, so that two faces sharing an edge get
// the same number, negated, at every pixel centre: they agree exactly on which side of it a
// centre lies.
struct Edge {
  double ux, uy, dx, dy, sign;
  Edge(const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
    const bool swap = q.x() < p.x() || (q.x() == p.x() && q.y() < p.y());
    const Eigen::Vector3d& u = swap ? q : p;
    const Eigen::Vector3d& v = swap ? p : q;
    ux = u.x(), uy = u.y(), dx = v.x() - u.x(), dy = v.y() - u.y(), sign = swap ? -1.0 : 1.0;
  }
  double operator()(double x, double y) const { return sign * (dx * (y - uy) - dy * (x - ux)); }
};

}  // namespace

std::string render_mesh_png(const std::vector<const Mesh*>& meshes, const RenderOptions& o) {
  std::vector<Eigen::Vector3d> all;
  for (const Mesh* m : meshes) all.insert(all.end(), m->vertices.begin(), m->vertices.end());
  const raster::Framing f = raster::frame(o, all);
  constexpr int S = raster::kSupersample;
  const int W = o.width * S, H = o.height * S;
  // The buffers are the thread's own, kept from picture to picture: first touching a fresh
  // 2048² picture's ~34 MB cost more than drawing it (page faults). Depth as float: view-space
  // millimetres to ~1e-5 mm, finer than OpenGL's 24-bit depth buffer over a hand.
  thread_local std::vector<std::uint8_t> rgba;
  thread_local std::vector<float> depth;
  const size_t n = static_cast<size_t>(W) * H;
  raster::clear_to_background(&rgba, n);
  depth.assign(n, -std::numeric_limits<float>::infinity());
  const raster::Lights lights;

  // Two passes. The first finds each pixel's nearest fragment (depth test, fill rule) and
  // keeps its face; the second colours each covered pixel once, from that face, with the
  // same edge functions: the colour of the fragment that was drawn last before, without
  // lighting, interpolating and sampling the texture for fragments later hidden (a hand seen
  // from any side hides about as much of itself as it shows).
  struct Face {
    Edge E0, E1, E2;
    double s;  // makes the face's edge functions positive inside
    int mesh;
    std::uint32_t index;  // in its mesh
  };
  struct Drawn {  // per mesh: window positions and lit colours of its vertices
    std::vector<Eigen::Vector3d> win;
    std::vector<std::array<Eigen::Vector3d, 2>> lit;
    const TextureMap* tex;
    double w_tex;
  };
  std::vector<Drawn> drawn(meshes.size());
  std::vector<Face> faces;
  thread_local std::vector<std::int32_t> nearest;  // per pixel: the face drawn there (into faces), or -1
  nearest.assign(n, -1);
  for (size_t m = 0; m < meshes.size(); ++m) {
    const Mesh& mesh = *meshes[m];
    const TextureMap* tex = m == 0 && o.texture && !o.texture->empty() ? o.texture : nullptr;
    HS_CHECK(!tex || tex->corner_uv.size() == mesh.n_faces(), "the texture's faces disagree with the mesh's");
    HS_CHECK(!tex || tex->rgb.size() == static_cast<size_t>(tex->size) * tex->size * 3, "the texture's image is not size x size RGB");
    HS_CHECK(faces.size() + mesh.faces.size() < static_cast<size_t>(std::numeric_limits<std::int32_t>::max()), "too many faces to draw");
    // A textured surface is lit white (0.92) and blended with the texture by its weight.
    const Eigen::Vector3f material = tex ? Eigen::Vector3f::Constant(0.92f) : o.colour;
    Drawn& d = drawn[m];
    d.tex = tex;
    d.w_tex = tex ? o.texture_weight : 0.0;
    // Per vertex: window position (x right, y down, supersampled pixels), view depth (larger
    // is nearer), and the lit colour of either side (two-sided lighting: the back of a face is
    // lit with the normal turned around).
    const std::vector<Eigen::Vector3d> normal = shading_normals(mesh);
    const size_t nv = mesh.vertices.size();
    d.win.resize(nv);
    d.lit.resize(nv);
    for (size_t v = 0; v < nv; ++v) {
      const Eigen::Vector3d q = o.view * mesh.vertices[v];
      d.win[v] << f.window(q), q.z();
      Eigen::Vector3d nrm = o.view * normal[v];
      if (nrm.squaredNorm() > 0) nrm.normalize();
      else nrm = Eigen::Vector3d::UnitZ();
      d.lit[v][0] = lights.shade(nrm, material);
      d.lit[v][1] = lights.shade(-nrm, material);
    }
    for (size_t fi = 0; fi < mesh.faces.size(); ++fi) {
      const auto& t = mesh.faces[fi];
      const Eigen::Vector3d &a = d.win[t[0]], &b = d.win[t[1]], &c = d.win[t[2]];
      // Twice the signed area with y down: negative for a face counter-clockwise as seen (its
      // front, as OpenGL's default, whose window y runs up).
      const double area = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
      if (!(std::abs(area) > 1e-12)) continue;
      const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}) - 0.5)));
      const int x1 = std::min(W - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}) - 0.5)));
      const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}) - 0.5)));
      const int y1 = std::min(H - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}) - 0.5)));
      if (x0 > x1 || y0 > y1) continue;
      // Each edge owns the pixel centres exactly on it only if it is a "top" or "left" edge of
      // the face wound one fixed way (as Direct3D's and OpenGL implementations' fill rule): two
      // faces sharing an edge then draw each such pixel once, never both, never neither.
      const double s = area < 0 ? -1.0 : 1.0;  // makes every face's weights positive inside
      const auto owns = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
        const double dx = s * (q.x() - p.x()), dy = s * (q.y() - p.y());
        return dy < 0 || (dy == 0 && dx > 0);
      };
      const bool own0 = owns(b, c), own1 = owns(c, a), own2 = owns(a, b);
      const Face F{Edge(b, c), Edge(c, a), Edge(a, b), s, static_cast<int>(m), static_cast<std::uint32_t>(fi)};
      const auto index = static_cast<std::int32_t>(faces.size());
      bool any = false;
      for (int y = y0; y <= y1; ++y) {
        const double py = y + 0.5;
        // The row's pixels that can be inside: each edge function is linear along the row,
        // so the centres where it is not negative are on one side of where it crosses zero.
        // That crossing is found to rounding (~1e-12 px) and widened by a pixel; every pixel
        // in the span is then tested exactly as before, so the span only skips pixels the
        // test would refuse.
        int xa = x0, xb = x1;
        for (const Edge* e : {&F.E0, &F.E1, &F.E2}) {
          // s·E(px, py) = k·(dx·(py − uy) − dy·(px − ux)), k = s·sign: c0 − m·(px − ux).
          const double k = s * e->sign, c0 = k * e->dx * (py - e->uy), m = k * e->dy;
          if (m == 0) {
            if (c0 < 0) xa = 1, xb = 0;  // the whole row outside (exactly, as the test finds)
            continue;
          }
          const double cross = e->ux + c0 / m - 0.5;  // pixel index whose centre is on the line
          if (!std::isfinite(cross)) continue;
          if (m < 0) {  // not negative right of the crossing
            if (cross - 1 > xa) xa = cross - 1 > x1 ? x1 + 1 : static_cast<int>(std::floor(cross - 1));
          } else {      // not negative left of it
            if (cross + 1 < xb) xb = cross + 1 < x0 ? x0 - 1 : static_cast<int>(std::ceil(cross + 1));
          }
        }
        for (int x = std::max(xa, x0); x <= std::min(xb, x1); ++x) {
          const double pxc = x + 0.5;
          // The edge functions (a pixel's weights before dividing by the area), inside when
          // none is negative (for the sign of the face's winding).
          const double e0 = s * F.E0(pxc, py), e1 = s * F.E1(pxc, py), e2 = s * F.E2(pxc, py);
          if (e0 < 0 || e1 < 0 || e2 < 0) continue;
          if ((e0 == 0 && !own0) || (e1 == 0 && !own1) || (e2 == 0 && !own2)) continue;
          const double sum = e0 + e1 + e2;
          if (!(sum > 0)) continue;
          const double l0 = e0 / sum, l1 = e1 / sum, l2 = e2 / sum;
          const size_t at = static_cast<size_t>(y) * W + x;
          const float z = static_cast<float>(l0 * a.z() + l1 * b.z() + l2 * c.z());
          if (!(z > depth[at])) continue;  // nearer only: the first drawn keeps a tie
          depth[at] = z;
          nearest[at] = index;
          any = true;
        }
      }
      if (any) faces.push_back(F);
    }
  }
  // The second pass: each covered pixel's colour from its face, its weights found again
  // exactly as the first pass found them.
  for (int y = 0; y < H; ++y) {
    const double py = y + 0.5;
    for (int x = 0; x < W; ++x) {
      const size_t at = static_cast<size_t>(y) * W + x;
      if (nearest[at] < 0) continue;
      const Face& F = faces[static_cast<size_t>(nearest[at])];
      const size_t fi = F.index;
      const Drawn& d = drawn[static_cast<size_t>(F.mesh)];
      const auto& t = meshes[static_cast<size_t>(F.mesh)]->faces[fi];
      const double pxc = x + 0.5;
      const double e0 = F.s * F.E0(pxc, py), e1 = F.s * F.E1(pxc, py), e2 = F.s * F.E2(pxc, py);
      const double sum = e0 + e1 + e2;
      const double l0 = e0 / sum, l1 = e1 / sum, l2 = e2 / sum;
      const int side = F.s < 0 ? 0 : 1;
      Eigen::Vector3d col = l0 * d.lit[t[0]][side] + l1 * d.lit[t[1]][side] + l2 * d.lit[t[2]][side];
      if (d.tex) {
        const auto& uv = d.tex->corner_uv[fi];
        const double u = l0 * uv[0].x() + l1 * uv[1].x() + l2 * uv[2].x();
        const double v = l0 * uv[0].y() + l1 * uv[1].y() + l2 * uv[2].y();
        col = d.w_tex * sample_bilinear(*d.tex, u, v) + (1 - d.w_tex) * col;
      }
      for (int ch = 0; ch < 3; ++ch) rgba[4 * at + ch] = raster::byte_of(col[ch]);
    }
  }
  raster::draw_dots(o, f, W, H, &rgba);
  return raster::downsample_png(rgba, o.width, o.height);
}

}  // namespace handskin
