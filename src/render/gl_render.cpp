// Pictures of meshes and skeletons with Mesa's off-screen OpenGL (OSMesa,
// Debian's libosmesa6-dev). llvmpipe rasterises on the CPU, so no display or GPU is needed,
// and the pictures get what a real renderer gives:
// - per-pixel depth;
// - smooth (Gouraud) shading from two lights with a little specular sheen;
// - two-sided lighting;
// - 2x supersampling for smooth edges.
// OSMesa rather than EGL surfaceless: one call to make a context on a memory buffer, in every
// Mesa build.
//
// Mesa is loaded when the first picture is drawn (or earlier, preload_gl), not when the program
// starts: libOSMesa brings LLVM, whose loading took ~0.1 s of every handskin process's start,
// and most commands draw nothing. The entry points below are pointers of the same names, filled
// from the library once; unqualified calls in namespace handskin find them before ::gl*.
#include <GL/gl.h>
#include <GL/osmesa.h>
#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <future>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "core/errors.hpp"
#include "core/png_io.hpp"
#include "render/preview.hpp"
#include "render/raster.hpp"

#define HS_GL_ENTRY_POINTS(X)                                                                                     \
  X(OSMesaCreateContextExt) X(OSMesaMakeCurrent) X(OSMesaPixelStore) X(OSMesaDestroyContext) X(glAlphaFunc)     \
  X(glBegin) X(glBindTexture) X(glClear) X(glClearColor) X(glColor3f) X(glColorMaterial) X(glDeleteTextures)    \
  X(glDisable) X(glDisableClientState) X(glDrawArrays) X(glDrawElements) X(glEnable) X(glEnableClientState)      \
  X(glEnd) X(glFinish) X(glGenTextures) X(glGetError) X(glLightModelfv) X(glLightModeli) X(glLightfv)            \
  X(glLineWidth) X(glLoadIdentity) X(glLoadMatrixd) X(glMaterialf) X(glMaterialfv) X(glMatrixMode)              \
  X(glNormalPointer) X(glOrtho) X(glPixelStorei) X(glPointSize) X(glPopAttrib) X(glPopClientAttrib)             \
  X(glPushAttrib) X(glPushClientAttrib) X(glShadeModel) X(glTexCoordPointer) X(glTexEnvfv) X(glTexEnvi)         \
  X(glTexImage2D) X(glTexParameteri) X(glVertex3d) X(glVertexPointer) X(glViewport)

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

void preload_gl() {
  // On a thread of its own, so that the loading overlaps the caller's work; a failure is said
  // again when a picture asks for the library.
  static std::future<void> loading = std::async(std::launch::async, [] {
    try {
      load_gl();
    } catch (const std::exception&) {
    }
  });
}

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
  return f;
}

std::string downsample_png(const std::vector<std::uint8_t>& rgba, int width, int height) {
  const int W = width * kSupersample;
  HS_CHECK(rgba.size() == static_cast<size_t>(W) * height * kSupersample * 4, "a picture's buffer is not its size");
  std::vector<std::uint8_t> rgb(static_cast<size_t>(width) * height * 3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        int sum = 0;
        for (int dy = 0; dy < kSupersample; ++dy)
          for (int dx = 0; dx < kSupersample; ++dx)
            sum += rgba[(static_cast<size_t>(y * kSupersample + dy) * W + x * kSupersample + dx) * 4 + ch];
        rgb[(static_cast<size_t>(y) * width + x) * 3 + ch] = static_cast<std::uint8_t>(sum / (kSupersample * kSupersample));
      }
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
    // Lights in view space (set under the identity modelview): key from the upper left, fill
    // from below.
    namespace L = raster::light;
    const auto gf = [](double v) { return static_cast<GLfloat>(v); };
    const GLfloat key[] = {gf(L::kKey[0]), gf(L::kKey[1]), gf(L::kKey[2]), 0.f}, fill[] = {gf(L::kFill[0]), gf(L::kFill[1]), gf(L::kFill[2]), 0.f};
    const GLfloat key_c[] = {gf(L::kKeyColour), gf(L::kKeyColour), gf(L::kKeyColour), 1.f},
                  fill_c[] = {gf(L::kFillColour), gf(L::kFillColour), gf(L::kFillColour), 1.f},
                  amb[] = {gf(L::kAmbient), gf(L::kAmbient), gf(L::kAmbient), 1.f};
    const GLfloat none[] = {0, 0, 0, 1};
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

  /// Joints or markers: red dots over everything.
  void dots(const std::vector<Eigen::Vector3d>& points) {
    if (points.empty()) return;
    glDisable(GL_LIGHTING);
    glDisable(GL_DEPTH_TEST);
    round_points(raster::kDotPx);
    glColor3f(raster::kDotColour[0] / 255.f, raster::kDotColour[1] / 255.f, raster::kDotColour[2] / 255.f);
    glBegin(GL_POINTS);
    for (const auto& p : points) glVertex3d(p.x(), p.y(), p.z());
    glEnd();
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

void lit_material(const Eigen::Vector3f& colour, bool per_vertex_colour) {
  const GLfloat sp = static_cast<GLfloat>(raster::light::kSpecular);
  const GLfloat c[] = {colour[0], colour[1], colour[2], 1.f}, spec[] = {sp, sp, sp, 1.f};
  glEnable(GL_LIGHTING);
  if (per_vertex_colour) {
    glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
    glEnable(GL_COLOR_MATERIAL);
  } else {
    glDisable(GL_COLOR_MATERIAL);
    glMaterialfv(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE, c);
  }
  glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, spec);
  glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, static_cast<GLfloat>(raster::light::kShininess));
}

// A texture bound for one draw, as the thesis blended photo and shading: texture unit 0
// interpolates between the lit white surface (the primary colour) and the texture by the
// constant weight, Arg0 * Arg2 + Arg1 * (1 - Arg2). `uv` (two per drawn vertex) must outlive it.
class BlendedTexture {
 public:
  BlendedTexture(const TextureMap& t, float weight, const std::vector<GLfloat>& uv) {
    lit_material(Eigen::Vector3f::Constant(0.92f), false);
    glGenTextures(1, &name_);
    glBindTexture(GL_TEXTURE_2D, name_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, t.size, t.size, 0, GL_RGB, GL_UNSIGNED_BYTE, t.rgb.data());
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    const GLfloat w[] = {weight, weight, weight, 1.f};
    glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_COMBINE);
    glTexEnvi(GL_TEXTURE_ENV, GL_COMBINE_RGB, GL_INTERPOLATE);
    glTexEnvi(GL_TEXTURE_ENV, GL_SOURCE0_RGB, GL_TEXTURE);
    glTexEnvi(GL_TEXTURE_ENV, GL_SOURCE1_RGB, GL_PRIMARY_COLOR);
    glTexEnvi(GL_TEXTURE_ENV, GL_SOURCE2_RGB, GL_CONSTANT);
    glTexEnvi(GL_TEXTURE_ENV, GL_OPERAND2_RGB, GL_SRC_COLOR);
    glTexEnvfv(GL_TEXTURE_ENV, GL_TEXTURE_ENV_COLOR, w);
    glEnable(GL_TEXTURE_2D);
    glEnableClientState(GL_TEXTURE_COORD_ARRAY);
    glTexCoordPointer(2, GL_FLOAT, 0, uv.data());
  }
  ~BlendedTexture() {
    glDisableClientState(GL_TEXTURE_COORD_ARRAY);
    glDisable(GL_TEXTURE_2D);
    glDeleteTextures(1, &name_);
  }
  BlendedTexture(const BlendedTexture&) = delete;
  BlendedTexture& operator=(const BlendedTexture&) = delete;

 private:
  GLuint name_ = 0;
};

}  // namespace

std::string render_mesh_png(const std::vector<const Mesh*>& meshes, const RenderOptions& o) {
  std::vector<Eigen::Vector3d> all;
  for (const Mesh* m : meshes) all.insert(all.end(), m->vertices.begin(), m->vertices.end());
  GlPicture pic(o, all);
  for (size_t m = 0; m < meshes.size(); ++m) {
    const Mesh& mesh = *meshes[m];
    const std::vector<Eigen::Vector3d> normal = shading_normals(mesh);
    const TextureMap* tex = m == 0 && o.texture && !o.texture->empty() ? o.texture : nullptr;
    HS_CHECK(!tex || tex->corner_uv.size() == mesh.n_faces(), "the texture's faces disagree with the mesh's");
    HS_CHECK(!tex || tex->rgb.size() == static_cast<size_t>(tex->size) * tex->size * 3, "the texture's image is not size x size RGB");
    // A textured mesh is drawn as a triangle soup (three corners a face): the corners of one
    // vertex may carry different texture coordinates. Otherwise indexed.
    std::vector<GLdouble> xyz, nrm;
    std::vector<GLfloat> uv;
    std::vector<GLuint> idx;
    const auto put = [&](int v) {
      const Eigen::Vector3d &p = mesh.vertices[static_cast<size_t>(v)], &n = normal[static_cast<size_t>(v)];
      xyz.insert(xyz.end(), {p[0], p[1], p[2]});
      nrm.insert(nrm.end(), {n[0], n[1], n[2]});
    };
    if (tex) {
      for (size_t f = 0; f < mesh.faces.size(); ++f)
        for (int k = 0; k < 3; ++k) {
          put(mesh.faces[f][k]);
          const Eigen::Vector2f& c = tex->corner_uv[f][k];
          uv.insert(uv.end(), {c.x(), c.y()});
        }
    } else {
      for (int v = 0; v < static_cast<int>(mesh.vertices.size()); ++v) put(v);
      for (const auto& f : mesh.faces)
        for (int v : f) idx.push_back(static_cast<GLuint>(v));
    }
    std::optional<BlendedTexture> blended;
    if (tex)
      blended.emplace(*tex, o.texture_weight, uv);
    else
      lit_material(o.colour, false);
    glEnableClientState(GL_VERTEX_ARRAY);
    glEnableClientState(GL_NORMAL_ARRAY);
    glVertexPointer(3, GL_DOUBLE, 0, xyz.data());
    glNormalPointer(GL_DOUBLE, 0, nrm.data());
    if (tex)
      glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(xyz.size() / 3));
    else
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(idx.size()), GL_UNSIGNED_INT, idx.data());
    glDisableClientState(GL_VERTEX_ARRAY);
    glDisableClientState(GL_NORMAL_ARRAY);
  }
  pic.dots(o.points);
  return pic.png();
}

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
