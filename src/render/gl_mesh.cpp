// Shaded meshes with Mesa's off-screen OpenGL (OSMesa, Debian's libosmesa6-dev): llvmpipe
// rasterises on the CPU, so no display or GPU is needed, and the pictures get what a real
// renderer gives — per-pixel depth, smooth (Gouraud) shading from two lights with a little
// specular sheen, two-sided lighting — at 2x supersampling for smooth edges. OSMesa rather
// than EGL surfaceless: one call to make a context on a memory buffer, in every Mesa build.
#include <GL/gl.h>
#include <GL/osmesa.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "core/errors.hpp"
#include "core/png_io.hpp"
#include "render/preview.hpp"

namespace handskin {

namespace {
constexpr int kSupersample = 2;

struct Context {
  OSMesaContext ctx = nullptr;
  std::vector<unsigned char> rgba;
  Context(int w, int h) : rgba(static_cast<size_t>(w) * h * 4) {
    ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
    HS_CHECK(ctx != nullptr, "OSMesa could not create an off-screen OpenGL context");
    HS_CHECK(OSMesaMakeCurrent(ctx, rgba.data(), GL_UNSIGNED_BYTE, w, h), "OSMesa could not bind its buffer");
    OSMesaPixelStore(OSMESA_Y_UP, 0);  // row 0 at the top, as PNG
  }
  ~Context() { OSMesaDestroyContext(ctx); }
};
}  // namespace

std::string render_mesh_png(const std::vector<const TriMesh*>& meshes, const RenderOptions& o) {
  HS_CHECK(o.width > 0 && o.height > 0, "empty picture");
  // The view-space box of every vertex: an orthographic camera fitted to it (92 % of the
  // picture, as the other previews).
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e18), hi = -lo;
  for (const TriMesh* m : meshes)
    for (auto v : m->vertices()) {
      const auto& p = m->point(v);
      const Eigen::Vector3d q = o.view * Eigen::Vector3d(p[0], p[1], p[2]);
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  HS_CHECK(hi.x() >= lo.x(), "nothing to render");
  const double scale = 0.92 * std::min(o.width / std::max(hi.x() - lo.x(), 1e-9), o.height / std::max(hi.y() - lo.y(), 1e-9));
  const Eigen::Vector3d c = 0.5 * (lo + hi);
  const double hw = 0.5 * o.width / scale, hh = 0.5 * o.height / scale, depth = std::max(1.0, hi.z() - lo.z());

  const int W = o.width * kSupersample, H = o.height * kSupersample;
  Context gl(W, H);
  glViewport(0, 0, W, H);
  glClearColor(246 / 255.f, 246 / 255.f, 248 / 255.f, 1);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  // View space looks down −Z with +Z toward the viewer: near and far about the box.
  glOrtho(c.x() - hw, c.x() + hw, c.y() - hh, c.y() + hh, -(hi.z() + depth), -(lo.z() - depth));
  glMatrixMode(GL_MODELVIEW);
  glLoadIdentity();
  // Lights in view space (set under the identity modelview): key from the upper left, fill
  // from below, as the software previews had them.
  const GLfloat key[] = {-0.4f, 0.5f, 1.0f, 0.f}, fill[] = {0.3f, -0.7f, 0.65f, 0.f};
  const GLfloat key_c[] = {0.63f, 0.63f, 0.63f, 1.f}, fill_c[] = {0.3f, 0.3f, 0.3f, 1.f}, amb[] = {0.22f, 0.22f, 0.22f, 1.f};
  const GLfloat spec[] = {0.12f, 0.12f, 0.12f, 1.f}, none[] = {0, 0, 0, 1};
  glEnable(GL_LIGHTING);
  glEnable(GL_LIGHT0);
  glEnable(GL_LIGHT1);
  glLightfv(GL_LIGHT0, GL_POSITION, key);
  glLightfv(GL_LIGHT0, GL_DIFFUSE, key_c);
  glLightfv(GL_LIGHT0, GL_SPECULAR, key_c);
  glLightfv(GL_LIGHT1, GL_POSITION, fill);
  glLightfv(GL_LIGHT1, GL_DIFFUSE, fill_c);
  glLightfv(GL_LIGHT1, GL_SPECULAR, none);
  glLightModelfv(GL_LIGHT_MODEL_AMBIENT, amb);
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  glShadeModel(GL_SMOOTH);
  glEnable(GL_NORMALIZE);
  const GLfloat colour[] = {o.colour[0], o.colour[1], o.colour[2], 1.f};
  glMaterialfv(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE, colour);
  glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, spec);
  glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, 24.f);
  GLdouble M[16] = {0};
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) M[4 * k + r] = o.view(r, k);  // column-major
  M[15] = 1;
  glLoadMatrixd(M);
  for (const TriMesh* m : meshes) {
    TriMesh mesh = *m;
    mesh.request_vertex_normals();
    mesh.request_face_normals();
    mesh.update_normals();
    std::vector<GLdouble> xyz, nrm;
    std::vector<GLuint> idx;
    for (auto v : mesh.vertices()) {
      const auto& p = mesh.point(v);
      const auto& n = mesh.normal(v);
      xyz.insert(xyz.end(), {p[0], p[1], p[2]});
      nrm.insert(nrm.end(), {n[0], n[1], n[2]});
    }
    for (auto f : mesh.faces())
      for (auto v : mesh.fv_range(f)) idx.push_back(static_cast<GLuint>(v.idx()));
    glEnableClientState(GL_VERTEX_ARRAY);
    glEnableClientState(GL_NORMAL_ARRAY);
    glVertexPointer(3, GL_DOUBLE, 0, xyz.data());
    glNormalPointer(GL_DOUBLE, 0, nrm.data());
    glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(idx.size()), GL_UNSIGNED_INT, idx.data());
    glDisableClientState(GL_VERTEX_ARRAY);
    glDisableClientState(GL_NORMAL_ARRAY);
  }
  // Joints or markers: red dots over everything.
  if (!o.points.empty()) {
    glDisable(GL_LIGHTING);
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_POINT_SMOOTH);
    glPointSize(7.f * kSupersample);
    glColor3f(200 / 255.f, 30 / 255.f, 40 / 255.f);
    glBegin(GL_POINTS);
    for (const auto& p : o.points) glVertex3d(p.x(), p.y(), p.z());
    glEnd();
  }
  glFinish();
  HS_CHECK(glGetError() == GL_NO_ERROR, "OpenGL reported an error while drawing");
  // Box filter down to the picture's size.
  std::vector<std::uint8_t> rgb(static_cast<size_t>(o.width) * o.height * 3);
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        int sum = 0;
        for (int dy = 0; dy < kSupersample; ++dy)
          for (int dx = 0; dx < kSupersample; ++dx)
            sum += gl.rgba[(static_cast<size_t>(y * kSupersample + dy) * W + x * kSupersample + dx) * 4 + ch];
        rgb[(static_cast<size_t>(y) * o.width + x) * 3 + ch] = static_cast<std::uint8_t>(sum / (kSupersample * kSupersample));
      }
  return encode_rgb8_png(o.width, o.height, rgb);
}

}  // namespace handskin
