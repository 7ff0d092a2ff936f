// Pictures of skeletons (`solve --png`: bones as smooth lines, joints as round points) with
// Mesa's off-screen OpenGL (OSMesa, Debian's libosmesa6-dev): llvmpipe rasterises on the CPU,
// so no display or GPU is needed; depth-tested, 2x supersampled for smooth edges. (Meshes and
// point clouds are drawn on the CPU by mesh_raster.cpp and splats.cpp, lit as OpenGL would.)
// OSMesa rather than EGL surfaceless: one call to make a context on a memory buffer, in every
// Mesa build.
//
// Mesa is loaded when the first picture is drawn, not when the program starts: libOSMesa brings LLVM, whose loading took ~0.1 s of every handskin process's start,
// and most commands draw nothing. The entry points below are pointers of the same names, filled
// from the library once; unqualified calls in namespace handskin find them before ::gl*.
#include <GL/gl.h>
#include <GL/osmesa.h>
#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <stdexcept>

#include "core/errors.hpp"
#include "core/png_io.hpp"
#include "render/preview.hpp"
#include "render/raster.hpp"

#define HS_GL_ENTRY_POINTS(X)                                                                                 \
  X(OSMesaCreateContextExt) X(OSMesaMakeCurrent) X(OSMesaPixelStore) X(OSMesaDestroyContext) X(glAlphaFunc) \
  X(glBegin) X(glClear) X(glClearColor) X(glColor3f) X(glDisable) X(glEnable) X(glEnd) X(glFinish)           \
  X(glGetError) X(glLineWidth) X(glLoadIdentity) X(glLoadMatrixd) X(glMatrixMode) X(glOrtho) X(glPointSize) \
  X(glPopAttrib) X(glPopClientAttrib) X(glPushAttrib) X(glPushClientAttrib) X(glVertex3d) X(glViewport)

namespace handskin {

namespace {
#define HS_GL_POINTER(f) decltype(&::f) f = nullptr;
HS_GL_ENTRY_POINTS(HS_GL_POINTER)
#undef HS_GL_POINTER

// Loads Mesa's off-screen OpenGL once (thread-safe); throws when it cannot be loaded.
void load_gl() {
  static std::once_flag once;
  static std::string failure;
  std::call_once(once, [] {
    void* lib = dlopen(HANDSKIN_OSMESA_SONAME, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
      failure = dlerror();
      return;
    }
#define HS_GL_LOAD(f)                                            \
  f = reinterpret_cast<decltype(f)>(dlsym(lib, #f));             \
  if (!f) {                                                      \
    failure = std::string(HANDSKIN_OSMESA_SONAME " has no ") + #f; \
    return;                                                      \
  }
    HS_GL_ENTRY_POINTS(HS_GL_LOAD)
#undef HS_GL_LOAD
  });
  if (!failure.empty())
    throw std::runtime_error("Mesa's off-screen OpenGL could not be loaded (Debian package libosmesa6): " + failure);
}
}  // namespace

namespace raster {

Framing frame(const RenderOptions& o, const std::vector<Eigen::Vector3d>& model_points) {
  HS_CHECK(o.width > 0 && o.height > 0, "empty picture");
  Framing f;
  f.lo = Eigen::Vector3d::Constant(1e18), f.hi = -f.lo;
  for (const auto& p : model_points) {
    const Eigen::Vector3d q = o.view * p;
    f.lo = f.lo.cwiseMin(q);
    f.hi = f.hi.cwiseMax(q);
  }
  HS_CHECK(f.hi.x() >= f.lo.x(), "nothing to render");
  f.scale = 0.92 * std::min(o.width / std::max(f.hi.x() - f.lo.x(), 1e-9), o.height / std::max(f.hi.y() - f.lo.y(), 1e-9));
  f.centre = 0.5 * (f.lo + f.hi);
  f.half_w = 0.5 * o.width / f.scale, f.half_h = 0.5 * o.height / f.scale;
  f.px = (o.width * kSupersample) / (2 * f.half_w);
  return f;
}

void downsample_rows(const std::uint8_t* band, int width, int row, int rows, std::vector<std::uint8_t>* rgb) {
  const int W = width * kSupersample;
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < width; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        int sum = 0;
        for (int dy = 0; dy < kSupersample; ++dy)
          for (int dx = 0; dx < kSupersample; ++dx)
            sum += band[(static_cast<size_t>(y * kSupersample + dy) * W + x * kSupersample + dx) * 4 + ch];
        (*rgb)[(static_cast<size_t>(row + y) * width + x) * 3 + ch] = static_cast<std::uint8_t>(sum / (kSupersample * kSupersample));
      }
}

std::string downsample_png(const std::vector<std::uint8_t>& rgba, int width, int height) {
  HS_CHECK(rgba.size() == static_cast<size_t>(width) * kSupersample * height * kSupersample * 4, "a picture's buffer is not its size");
  std::vector<std::uint8_t> rgb(static_cast<size_t>(width) * height * 3);
  downsample_rows(rgba.data(), width, 0, height, &rgb);
  return encode_rgb8_png(width, height, rgb);
}

}  // namespace raster

namespace {
using raster::kSupersample;

// One picture: an orthographic camera fitted to view-space points (92 % of the frame, as
// the range-image previews), the lights, and the view rotation as the modelview.
class GlPicture {
 public:
  GlPicture(const RenderOptions& o, const std::vector<Eigen::Vector3d>& model_points) : o_(o) {
    const raster::Framing f = raster::frame(o, model_points);
    scale_ = f.scale;
    const Eigen::Vector3d &c = f.centre, &lo = f.lo, &hi = f.hi;
    const double hw = f.half_w, hh = f.half_h, depth = std::max(1.0, hi.z() - lo.z());
    W_ = o.width * kSupersample;
    H_ = o.height * kSupersample;
    rgba_.resize(static_cast<size_t>(W_) * H_ * 4);
    const OSMesaContext ctx = context();  // first: it loads the entry points the calls below go through
    HS_CHECK(OSMesaMakeCurrent(ctx, rgba_.data(), GL_UNSIGNED_BYTE, W_, H_), "OSMesa could not bind its buffer");
    OSMesaPixelStore(OSMESA_Y_UP, 0);  // row 0 at the top, as PNG
    // Every picture starts from OpenGL's initial state; the destructor restores it.
    glPushAttrib(GL_ALL_ATTRIB_BITS);
    glPushClientAttrib(GL_CLIENT_ALL_ATTRIB_BITS);
    glViewport(0, 0, W_, H_);
    glClearColor(raster::kBackground[0] / 255.f, raster::kBackground[1] / 255.f, raster::kBackground[2] / 255.f, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glMatrixMode(GL_PROJECTION);
    glLoadIdentity();
    // View space looks down −Z with +Z toward the viewer: near and far about the box.
    glOrtho(c.x() - hw, c.x() + hw, c.y() - hh, c.y() + hh, -(hi.z() + depth), -(lo.z() - depth));
    glMatrixMode(GL_MODELVIEW);
    glLoadIdentity();
    GLdouble M[16] = {0};
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) M[4 * k + r] = o.view(r, k);  // column-major
    M[15] = 1;
    glLoadMatrixd(M);
  }
  ~GlPicture() {
    glPopClientAttrib();
    glPopAttrib();
  }
  GlPicture(const GlPicture&) = delete;
  GlPicture& operator=(const GlPicture&) = delete;

  double scale() const { return scale_; }  ///< output pixels per mm

  /// Round dots of `diameter` output pixels (alpha-tested smooth points, depth-tested unless
  /// `on_top`).
  static void round_points(double diameter) {
    glEnable(GL_POINT_SMOOTH);
    glEnable(GL_ALPHA_TEST);
    glAlphaFunc(GL_GREATER, 0.5f);
    glPointSize(static_cast<GLfloat>(std::max(1.0, diameter * kSupersample)));
  }

  /// Box filter down to the picture's size, PNG.
  std::string png() {
    glFinish();
    HS_CHECK(glGetError() == GL_NO_ERROR, "OpenGL reported an error while drawing");
    return raster::downsample_png(rgba_, o_.width, o_.height);
  }

 private:
  const RenderOptions& o_;
  double scale_ = 1;
  int W_ = 0, H_ = 0;
  std::vector<std::uint8_t> rgba_;

  // The thread's context, made at its first picture and kept for its next ones: a new context
  // costs ~20 ms before anything is drawn (llvmpipe compiles its shaders for each), and a run
  // draws six posed skins in a row. Rebound to each picture's buffer.
  static OSMesaContext context() {
    struct Kept {
      OSMesaContext ctx = nullptr;
      ~Kept() {
        if (ctx) OSMesaDestroyContext(ctx);
      }
    };
    thread_local Kept kept;
    if (!kept.ctx) {
      load_gl();
      kept.ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
      HS_CHECK(kept.ctx != nullptr, "OSMesa could not create an off-screen OpenGL context");
    }
    return kept.ctx;
  }
};

}  // namespace

std::string render_skeletons_png(const std::vector<SkeletonDrawing>& skeletons, const RenderOptions& o) {
  std::vector<Eigen::Vector3d> all;
  for (const auto& sk : skeletons) all.insert(all.end(), sk.joints.begin(), sk.joints.end());
  HS_CHECK(!all.empty(), "no joints to draw");
  GlPicture pic(o, all);
  glDisable(GL_LIGHTING);
  glEnable(GL_LINE_SMOOTH);
  glLineWidth(3.2f * kSupersample);
  for (const auto& sk : skeletons) {
    HS_CHECK(sk.joints.size() == sk.parents.size(), "joints and parents differ in length");
    glColor3f(sk.colour[0], sk.colour[1], sk.colour[2]);
    glBegin(GL_LINES);
    for (size_t j = 0; j < sk.joints.size(); ++j) {
      if (sk.parents[j] < 0) continue;
      const auto& a = sk.joints[j];
      const auto& b = sk.joints[sk.parents[j]];
      glVertex3d(a.x(), a.y(), a.z());
      glVertex3d(b.x(), b.y(), b.z());
    }
    glEnd();
    GlPicture::round_points(8);
    glBegin(GL_POINTS);
    for (const auto& p : sk.joints) glVertex3d(p.x(), p.y(), p.z());
    glEnd();
  }
  return pic.png();
}

}  // namespace handskin
