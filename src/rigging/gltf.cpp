#include "rigging/gltf.hpp"

#include <filesystem>

#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <map>
#include <sstream>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/png_io.hpp"

namespace handskin {

namespace {

constexpr double kMetre = 1e-3;  // mm → m
constexpr const char* kFormat = "handskin-rigged-skin/1";

tinygltf::Value to_value(const Json& j) {
  if (j.is_null()) return tinygltf::Value();
  if (j.is_boolean()) return tinygltf::Value(j.get<bool>());
  if (j.is_number_integer() && std::abs(j.get<long long>()) < (1LL << 31)) return tinygltf::Value(static_cast<int>(j.get<long long>()));
  if (j.is_number()) return tinygltf::Value(j.get<double>());
  if (j.is_string()) return tinygltf::Value(j.get<std::string>());
  if (j.is_array()) {
    tinygltf::Value::Array a;
    for (const auto& e : j) a.push_back(to_value(e));
    return tinygltf::Value(std::move(a));
  }
  tinygltf::Value::Object o;
  for (auto it = j.begin(); it != j.end(); ++it) o[it.key()] = to_value(it.value());
  return tinygltf::Value(std::move(o));
}

Json from_value(const tinygltf::Value& v) {
  if (v.IsBool()) return v.Get<bool>();
  if (v.IsInt()) return v.Get<int>();
  if (v.IsNumber()) return v.GetNumberAsDouble();
  if (v.IsString()) return v.Get<std::string>();
  if (v.IsArray()) {
    Json a = Json::array();
    for (size_t k = 0; k < v.ArrayLen(); ++k) a.push_back(from_value(v.Get(static_cast<int>(k))));
    return a;
  }
  if (v.IsObject()) {
    Json o = Json::object();
    for (const auto& key : v.Keys()) o[key] = from_value(v.Get(key));
    return o;
  }
  return nullptr;
}

// Append raw bytes to the one buffer, 4-byte aligned, as a view; returns the view's index.
int add_view(tinygltf::Model& m, const void* data, size_t bytes, int target) {
  auto& buf = m.buffers[0].data;
  while (buf.size() % 4) buf.push_back(0);
  tinygltf::BufferView v;
  v.buffer = 0;
  v.byteOffset = buf.size();
  v.byteLength = bytes;
  v.target = target;
  const auto* p = static_cast<const unsigned char*>(data);
  buf.insert(buf.end(), p, p + bytes);
  m.bufferViews.push_back(v);
  return static_cast<int>(m.bufferViews.size()) - 1;
}

int add_accessor(tinygltf::Model& m, int view, int component, int type, size_t count, std::vector<double> lo = {},
                 std::vector<double> hi = {}) {
  tinygltf::Accessor a;
  a.bufferView = view;
  a.componentType = component;
  a.type = type;
  a.count = count;
  a.minValues = std::move(lo);
  a.maxValues = std::move(hi);
  m.accessors.push_back(a);
  return static_cast<int>(m.accessors.size()) - 1;
}

std::vector<double> quat_xyzw(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1;  // one sign: the same input writes the same bytes
  return {q.x(), q.y(), q.z(), q.w()};
}

// The palm frame (Z up from the table) in glTF's Y-up frame: (x, y, z) → (x, z, −y).
Eigen::Matrix3d palm_to_gltf() {
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return R;
}

// Keep an image's encoded bytes as they are: read_skin_glb decodes the texture itself, so
// that what it accepts (a square 8-bit RGB PNG) and its errors are its own.
bool keep_image_bytes(tinygltf::Image* image, const int, std::string*, std::string*, int, int, const unsigned char* bytes,
                      int size, void*) {
  image->image.assign(bytes, bytes + size);
  return true;
}

}  // namespace

std::array<JointNode, kJointCount> joint_nodes(const Skeleton& skel, const Angles& angles) {
  const auto posed = skel.frames(angles);
  std::array<JointNode, kJointCount> out;
  for (int j = 0; j < kJointCount; ++j) {
    const int p = joints()[j].parent;
    const Eigen::Isometry3d local = p < 0 ? posed[j] : Eigen::Isometry3d(posed[p].inverse() * posed[j]);
    const Eigen::Vector3d t = local.translation() * kMetre;
    const std::vector<double> q = quat_xyzw(local.linear());
    out[j].translation = {t.x(), t.y(), t.z()};
    out[j].rotation = {q[0], q[1], q[2], q[3]};
  }
  return out;
}

namespace {

constexpr int kFirstJoint = 2;  // the glb's node of the first joint (0 the mesh, 1 "hand")

// Vertex attributes of the glb's mesh, in glTF's units (metres) and types.
struct VertexArrays {
  std::vector<float> pos, nrm, wts;
  std::vector<std::uint8_t> jts;
  std::vector<double> lo, hi;  ///< the positions' bounds
};

// With a texture, a vertex is written once per distinct texture coordinate of its corners:
// the skin's vertices first (each with its first corner's), then the copies. `source`: per
// written vertex, the skin's vertex it copies; `uv` its texture coordinate; `faces` the
// faces over the written vertices. Without a texture, the skin's own.
void split_seams(const RiggedSkin& s, bool textured, std::vector<int>* source, std::vector<Eigen::Vector2f>* uv,
                 std::vector<std::array<int, 3>>* faces) {
  source->resize(s.mesh.vertices.size());
  for (size_t i = 0; i < source->size(); ++i) (*source)[i] = static_cast<int>(i);
  uv->assign(textured ? s.mesh.vertices.size() : 0, Eigen::Vector2f::Constant(-1));
  *faces = s.mesh.faces;
  if (textured) {
    std::map<std::pair<int, std::pair<float, float>>, int> copies;
    for (size_t f = 0; f < faces->size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int v = s.mesh.faces[f][k];
        const Eigen::Vector2f& c = s.texture.corner_uv[f][k];
        if ((*uv)[v].x() < 0) (*uv)[v] = c;
        if ((*uv)[v] == c) continue;
        const auto key = std::make_pair(v, std::make_pair(c.x(), c.y()));
        auto it = copies.find(key);
        if (it == copies.end()) {
          it = copies.emplace(key, static_cast<int>(source->size())).first;
          source->push_back(v);
          uv->push_back(c);
        }
        (*faces)[f][k] = it->second;
      }
    for (auto& c : *uv) c = c.x() < 0 ? Eigen::Vector2f::Zero() : c;  // a vertex in no face
  }
}

// Positions (metres), normals, and each vertex's joints and weights (a link's weight goes to
// its first joint).
VertexArrays vertex_arrays(const RiggedSkin& s, const std::vector<int>& source) {
  const size_t n = source.size();
  VertexArrays a;
  std::vector<float>& pos = a.pos;
  std::vector<float>& nrm = a.nrm;
  std::vector<float>& wts = a.wts;
  std::vector<std::uint8_t>& jts = a.jts;
  std::vector<double>& lo = a.lo;
  std::vector<double>& hi = a.hi;
  pos.resize(3 * n), nrm.assign(3 * n, 0.0f), wts.assign(4 * n, 0.0f);
  jts.assign(4 * n, 0);
  lo.assign(3, 1e300), hi.assign(3, -1e300);
  const std::vector<Eigen::Vector3d> normal = vertex_normals(s.mesh.vertices, s.mesh.faces);
  for (size_t out_i = 0; out_i < n; ++out_i) {
    const size_t i = static_cast<size_t>(source[out_i]);
    for (int c = 0; c < 3; ++c) {
      pos[3 * out_i + c] = static_cast<float>(s.mesh.vertices[i](c) * kMetre);
      lo[c] = std::min(lo[c], static_cast<double>(pos[3 * out_i + c]));
      hi[c] = std::max(hi[c], static_cast<double>(pos[3 * out_i + c]));
    }
    for (int c = 0; c < 3; ++c) nrm[3 * out_i + c] = static_cast<float>(normal[i](c));
    // A link's weight goes to its first joint; links that share it are summed.
    std::array<std::pair<int, double>, kMaxInfluences> jw{};
    int used = 0;
    const VertexWeights& w = s.binding.vertices[i];
    for (int k = 0; k < kMaxInfluences && w.link[k] >= 0; ++k) {
      const int j = link_joint(w.link[k]);
      int slot = 0;
      while (slot < used && jw[slot].first != j) ++slot;
      if (slot == used) jw[used++] = {j, 0.0};
      jw[slot].second += w.weight[k];
    }
    double sum = 0;
    for (int k = 0; k < used; ++k) sum += jw[k].second;
    // Normalised only when they need it, so that weights read back from a glb are written
    // unchanged (a posed glb then poses exactly as the one it came from).
    const double scale = std::abs(sum - 1) > 1e-6 ? 1 / sum : 1.0;
    for (int k = 0; k < used; ++k) {
      jts[4 * out_i + k] = static_cast<std::uint8_t>(jw[k].first);
      wts[4 * out_i + k] = static_cast<float>(jw[k].second * scale);
    }
  }
  return a;
}

// The skin's mesh (primitive 0), its material and, with a texture, its image.
void add_mesh(tinygltf::Model& m, const RiggedSkin& s, const VertexArrays& a, size_t n,
              const std::vector<std::array<int, 3>>& faces, const std::vector<Eigen::Vector2f>& uv, bool textured) {
  std::vector<std::uint32_t> idx;
  for (const auto& f : faces)
    for (int k : f) idx.push_back(static_cast<std::uint32_t>(k));
  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.attributes["POSITION"] = add_accessor(m, add_view(m, a.pos.data(), a.pos.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER),
                                             TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n, a.lo, a.hi);
  prim.attributes["NORMAL"] = add_accessor(m, add_view(m, a.nrm.data(), a.nrm.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER),
                                           TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
  prim.attributes["JOINTS_0"] = add_accessor(m, add_view(m, a.jts.data(), a.jts.size(), TINYGLTF_TARGET_ARRAY_BUFFER),
                                             TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC4, n);
  prim.attributes["WEIGHTS_0"] = add_accessor(m, add_view(m, a.wts.data(), a.wts.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER),
                                              TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, n);
  prim.indices = add_accessor(m, add_view(m, idx.data(), idx.size() * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER),
                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, idx.size());
  tinygltf::Material mat;
  mat.name = "skin";
  mat.pbrMetallicRoughness.baseColorFactor = {0.87, 0.72, 0.62, 1.0};
  if (textured) {
    std::vector<float> tc;
    for (const auto& c : uv) tc.insert(tc.end(), {c.x(), c.y()});
    prim.attributes["TEXCOORD_0"] = add_accessor(m, add_view(m, tc.data(), tc.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER),
                                                 TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, n);
    const std::string png = s.texture_png.empty() ? encode_rgb8_png(s.texture.size, s.texture.size, s.texture.rgb) : s.texture_png;
    tinygltf::Image image;
    image.name = "skin";
    image.mimeType = "image/png";
    image.bufferView = add_view(m, png.data(), png.size(), -1);
    m.bufferViews.back().target = 0;
    m.images.push_back(image);
    tinygltf::Sampler sampler;
    sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
    sampler.wrapS = sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    m.samplers.push_back(sampler);
    tinygltf::Texture texture;
    texture.source = 0;
    texture.sampler = 0;
    m.textures.push_back(texture);
    mat.pbrMetallicRoughness.baseColorFactor = {1.0, 1.0, 1.0, 1.0};
    mat.pbrMetallicRoughness.baseColorTexture.index = 0;
  }
  mat.pbrMetallicRoughness.metallicFactor = 0.0;
  mat.pbrMetallicRoughness.roughnessFactor = 0.6;
  m.materials.push_back(mat);
  prim.material = 0;
  tinygltf::Mesh mesh;
  mesh.name = "skin";
  mesh.primitives.push_back(prim);
  m.meshes.push_back(mesh);

}

// Nodes: 0 the skinned mesh, 1 "hand" (the frame turn), 2.. the 25 joints (at `nodes`).
void add_nodes(tinygltf::Model& m, const std::array<JointNode, kJointCount>& nodes) {
  tinygltf::Node mesh_node;
  mesh_node.name = "skin";
  mesh_node.mesh = 0;
  mesh_node.skin = 0;
  m.nodes.push_back(mesh_node);
  tinygltf::Node hand;
  hand.name = "hand";
  hand.rotation = quat_xyzw(palm_to_gltf());
  m.nodes.push_back(hand);
  for (int j = 0; j < kJointCount; ++j) {
    tinygltf::Node node;
    node.name = joints()[j].name;
    node.translation.assign(nodes[j].translation.begin(), nodes[j].translation.end());
    node.rotation.assign(nodes[j].rotation.begin(), nodes[j].rotation.end());
    m.nodes.push_back(node);
  }
  for (int j = 0; j < kJointCount; ++j) {
    const int p = joints()[j].parent;
    (p < 0 ? m.nodes[1] : m.nodes[kFirstJoint + p]).children.push_back(kFirstJoint + j);
  }
}

// The skin: the joints and their inverse bind matrices (the rest posture).
void add_skin(tinygltf::Model& m, const std::array<Eigen::Isometry3d, kJointCount>& rest) {
  std::vector<float> ibm;
  for (int j = 0; j < kJointCount; ++j) {
    Eigen::Isometry3d r = rest[j];
    r.translation() *= kMetre;
    const Eigen::Matrix4d inv = r.inverse().matrix();
    for (int c = 0; c < 4; ++c)  // column-major
      for (int rr = 0; rr < 4; ++rr) ibm.push_back(static_cast<float>(inv(rr, c)));
  }
  tinygltf::Skin skin;
  skin.name = "hand";
  skin.skeleton = kFirstJoint;
  for (int j = 0; j < kJointCount; ++j) skin.joints.push_back(kFirstJoint + j);
  skin.inverseBindMatrices =
      add_accessor(m, add_view(m, ibm.data(), ibm.size() * 4, -1), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_MAT4, kJointCount);
  m.bufferViews.back().target = 0;
  m.skins.push_back(skin);
}

// The animation "handskin": a rotation channel per joint whose frames differ from its node,
// and the wrist's translation.
void add_animation(tinygltf::Model& m, const Skeleton& skel, const std::array<JointNode, kJointCount>& nodes,
                   const PostureAnimation* animation) {
  HS_CHECK(animation->times.size() == animation->frames.size(), "animation: times and frames differ");
  const size_t nf = animation->frames.size();
  std::vector<std::array<JointNode, kJointCount>> at;
  for (const Angles& f : animation->frames) at.push_back(joint_nodes(skel, f));
  std::vector<float> times;
  for (double t : animation->times) times.push_back(static_cast<float>(t));
  tinygltf::Animation an;
  an.name = "handskin";
  const int input = add_accessor(m, add_view(m, times.data(), times.size() * 4, 0), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                 TINYGLTF_TYPE_SCALAR, nf, {times.front()}, {times.back()});
  auto channel = [&](const std::vector<float>& values, int type, int node, const char* path) {
    tinygltf::AnimationSampler sampler;
    sampler.input = input;
    sampler.output = add_accessor(m, add_view(m, values.data(), values.size() * 4, 0), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                  type, nf);
    sampler.interpolation = "LINEAR";
    an.samplers.push_back(sampler);
    tinygltf::AnimationChannel c;
    c.sampler = static_cast<int>(an.samplers.size()) - 1;
    c.target_node = node;
    c.target_path = path;
    an.channels.push_back(c);
  };
  for (int j = 0; j < kJointCount; ++j) {
    std::vector<float> q;
    std::array<double, 4> prev = at[0][j].rotation;
    bool varies = false;
    for (size_t f = 0; f < nf; ++f) {
      std::array<double, 4> r = at[f][j].rotation;
      double dot = 0;
      for (int c = 0; c < 4; ++c) dot += r[c] * prev[c];
      if (dot < 0)
        for (double& c : r) c = -c;
      // A channel wherever a frame differs from the node's own rotation (the rest, or `pose`).
      double to_node = 0;
      for (int c = 0; c < 4; ++c) to_node += r[c] * nodes[j].rotation[c];
      varies = varies || std::abs(std::abs(to_node) - 1) > 1e-12;
      for (double c : r) q.push_back(static_cast<float>(c));
      prev = r;
    }
    if (varies || j == 0) channel(q, TINYGLTF_TYPE_VEC4, kFirstJoint + j, "rotation");
  }
  std::vector<float> wrist;
  for (size_t f = 0; f < nf; ++f)
    for (double c : at[f][0].translation) wrist.push_back(static_cast<float>(c));
  channel(wrist, TINYGLTF_TYPE_VEC3, kFirstJoint, "translation");
  m.animations.push_back(an);
}

// The scene, with the rig, the posture model and the binding in its extras.
void add_scene(tinygltf::Model& m, const RiggedSkin& s, const Angles* pose, const std::vector<int>& source, bool textured) {
  tinygltf::Scene scene;
  scene.name = "handskin";
  scene.nodes = {0, 1};
  Json extras = {{"format", kFormat},
                 {"units", "the rig in mm, palm frame; glTF positions in metres"},
                 {"rig", Json::parse(rig_to_json_text(s.rig))},
                 {"posture_model", model_to_json(s.model)},
                 {"binding", s.binding.mode}};
  if (pose) extras["pose_deg"] = std::vector<double>(pose->begin(), pose->end());
  if (textured) extras["seam_sources"] = std::vector<int>(source.begin() + static_cast<long>(s.mesh.vertices.size()), source.end());
  scene.extras = to_value(Json{{"handskin", extras}});
  m.scenes.push_back(scene);
  m.defaultScene = 0;

}

}  // namespace

std::vector<unsigned char> skin_glb(const RiggedSkin& s, const Angles* pose, const PostureAnimation* animation) {
  HS_CHECK(s.mesh.vertices.size() == s.binding.vertices.size(), "binding and mesh differ in size");
  const Skeleton skel(s.rig);
  Angles zero{};
  const auto rest = skel.frames(zero);
  const auto nodes = joint_nodes(skel, pose ? *pose : zero);
  tinygltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "handskin";
  m.buffers.emplace_back();
  const bool textured = !s.texture.empty();
  HS_CHECK(!textured || s.texture.corner_uv.size() == s.mesh.faces.size(), "texture and mesh differ in faces");
  std::vector<int> source;
  std::vector<Eigen::Vector2f> uv;
  std::vector<std::array<int, 3>> faces;
  split_seams(s, textured, &source, &uv, &faces);
  add_mesh(m, s, vertex_arrays(s, source), source.size(), faces, uv, textured);
  add_nodes(m, nodes);
  add_skin(m, rest);
  if (animation && !animation->frames.empty()) add_animation(m, skel, nodes, animation);
  add_scene(m, s, pose, source, textured);

  std::ostringstream out;
  tinygltf::TinyGLTF gltf;
  HS_CHECK(gltf.WriteGltfSceneToStream(&m, out, false, true), "glTF writing failed");
  const std::string bytes = out.str();
  return {bytes.begin(), bytes.end()};
}

namespace {

// Floats of accessor `index` (of glTF type `type`), checked against its buffer and finite.
std::vector<float> accessor_floats(const tinygltf::Model& m, const std::string& file, int index, int type,
                                   const char* what) {
  if (index < 0 || index >= static_cast<int>(m.accessors.size())) throw InputError(file, std::string(what) + ": no accessor");
  const tinygltf::Accessor& a = m.accessors[index];
  if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || a.type != type || a.bufferView < 0)
    throw InputError(file, std::string(what) + ": expected float data of its type");
  const tinygltf::BufferView& v = m.bufferViews[a.bufferView];
  const int comps = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(type));
  const size_t need = a.byteOffset + a.count * comps * 4;
  if ((v.byteStride && v.byteStride != static_cast<size_t>(comps) * 4) || need > v.byteLength ||
      v.byteOffset + v.byteLength > m.buffers[v.buffer].data.size())
    throw InputError(file, std::string(what) + ": accessor out of its buffer");
  std::vector<float> out(a.count * comps);
  std::memcpy(out.data(), m.buffers[v.buffer].data.data() + v.byteOffset + a.byteOffset, out.size() * 4);
  for (float f : out)
    if (!std::isfinite(f)) throw InputError(file, std::string(what) + ": a value is not finite");
  return out;
}

// The skin's 25 joints: per skin joint, our joint index.
std::array<int, kJointCount> skin_joints(const tinygltf::Model& m, const std::string& file) {
  if (m.skins.size() != 1) throw InputError(file, "expected one skin, found " + std::to_string(m.skins.size()));
  const tinygltf::Skin& sk = m.skins[0];
  if (static_cast<int>(sk.joints.size()) != kJointCount)
    throw InputError(file, "the skin has " + std::to_string(sk.joints.size()) + " joints, expected 25");
  std::array<int, kJointCount> ours{};
  for (int k = 0; k < kJointCount; ++k) {
    const int node = sk.joints[k];
    if (node < 0 || node >= static_cast<int>(m.nodes.size())) throw InputError(file, "a skin joint names no node");
    const auto j = joint_index(m.nodes[node].name);
    if (!j) throw InputError(file, "skin joint '" + m.nodes[node].name + "' is not one of the 25 WebXR hand joints");
    ours[k] = *j;
  }
  return ours;
}

// Bind matrices: finite, and the rig's rest frames (else the file was edited apart).
void check_bind_matrices(const tinygltf::Model& m, const std::string& file, const Rig& rig,
                         const std::array<int, kJointCount>& ours) {
  const tinygltf::Skin& sk = m.skins[0];
  const std::vector<float> ibm = accessor_floats(m, file, sk.inverseBindMatrices, TINYGLTF_TYPE_MAT4, "inverse bind matrices");
  if (ibm.size() != 16u * kJointCount) throw InputError(file, "inverse bind matrices: expected 25");
  const Skeleton skel(rig);
  for (int k = 0; k < kJointCount; ++k) {
    Eigen::Matrix4d M;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) M(r, c) = ibm[16 * k + 4 * c + r];
    Eigen::Isometry3d rest = skel.rest_frame(ours[k]);
    rest.translation() *= kMetre;
    if ((M - rest.inverse().matrix()).cwiseAbs().maxCoeff() > 1e-4)
      throw InputError(file, std::string("the inverse bind matrix of ") + joints()[ours[k]].name + " does not match the rig");
  }
}

// The skinned node's primitive.
const tinygltf::Primitive& skin_primitive(const tinygltf::Model& m, const std::string& file) {
  int mesh = -1;
  for (const auto& n : m.nodes)
    if (n.skin == 0 && n.mesh >= 0) mesh = n.mesh;
  if (mesh < 0 || m.meshes[mesh].primitives.size() != 1) throw InputError(file, "no skinned mesh with one primitive");
  return m.meshes[mesh].primitives[0];
}

// A primitive's attribute's accessor.
int attribute(const tinygltf::Primitive& prim, const std::string& file, const char* name) {
  const auto it = prim.attributes.find(name);
  if (it == prim.attributes.end()) throw InputError(file, std::string("the skin mesh has no ") + name);
  return it->second;
}

// The vertices (mm) and their weights back on the rig's links.
void read_vertices(const tinygltf::Model& m, const tinygltf::Primitive& prim, const std::string& file,
                   const std::array<int, kJointCount>& ours, RiggedSkin* sp) {
  RiggedSkin& s = *sp;
  auto attr = [&](const char* name) { return attribute(prim, file, name); };
  const std::vector<float> pos = accessor_floats(m, file, attr("POSITION"), TINYGLTF_TYPE_VEC3, "POSITION");
  const std::vector<float> wts = accessor_floats(m, file, attr("WEIGHTS_0"), TINYGLTF_TYPE_VEC4, "WEIGHTS_0");
  const size_t n = pos.size() / 3;
  if (wts.size() != 4 * n) throw InputError(file, "WEIGHTS_0 and POSITION differ in count");
  const tinygltf::Accessor& ja = m.accessors[attr("JOINTS_0")];
  if (ja.type != TINYGLTF_TYPE_VEC4 || ja.count != n || ja.bufferView < 0 ||
      (ja.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ja.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT))
    throw InputError(file, "JOINTS_0 must be 4 unsigned bytes or shorts per vertex");
  const tinygltf::BufferView& jv = m.bufferViews[ja.bufferView];
  const size_t jsize = ja.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ? 1 : 2;
  if (ja.byteOffset + n * 4 * jsize > jv.byteLength || jv.byteOffset + jv.byteLength > m.buffers[jv.buffer].data.size())
    throw InputError(file, "JOINTS_0: accessor out of its buffer");
  const unsigned char* jp = m.buffers[jv.buffer].data.data() + jv.byteOffset + ja.byteOffset;
  // A joint's weight back to a link that moves with it (any: they move alike).
  std::array<int, kJointCount> link_of{};
  link_of.fill(-1);
  for (int k = kJointCount - 2; k >= 0; --k) link_of[link_joint(k)] = k;
  for (size_t i = 0; i < n; ++i) {
    s.mesh.vertices.emplace_back(pos[3 * i] / kMetre, pos[3 * i + 1] / kMetre, pos[3 * i + 2] / kMetre);
    VertexWeights w;
    double sum = 0;
    int used = 0;
    for (int k = 0; k < 4; ++k) {
      const unsigned idx = jsize == 1 ? jp[4 * i + k] : static_cast<unsigned>(jp[8 * i + 2 * k] | (jp[8 * i + 2 * k + 1] << 8));
      const float wt = wts[4 * i + k];
      if (wt < 0) throw InputError(file, "WEIGHTS_0: a negative weight at vertex " + std::to_string(i));
      if (wt == 0) continue;
      if (idx >= static_cast<unsigned>(kJointCount)) throw InputError(file, "JOINTS_0: joint index out of range at vertex " + std::to_string(i));
      const int link = link_of[ours[idx]];
      if (link < 0) throw InputError(file, std::string("vertex ") + std::to_string(i) + " is weighted to a fingertip joint, which moves nothing");
      w.link[used] = link;
      w.weight[used] = wt;
      sum += wt;
      ++used;
    }
    if (used == 0 || std::abs(sum - 1) > 1e-3)
      throw InputError(file, "WEIGHTS_0: the weights of vertex " + std::to_string(i) + " do not sum to 1");
    s.binding.vertices.push_back(w);
  }
}

// The triangles over the vertices.
void read_triangles(const tinygltf::Model& m, const tinygltf::Primitive& prim, const std::string& file, RiggedSkin* sp) {
  RiggedSkin& s = *sp;
  const size_t n = s.mesh.vertices.size();
  if (prim.indices < 0) throw InputError(file, "the skin mesh has no indices");
  const tinygltf::Accessor& ia = m.accessors[prim.indices];
  if (ia.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT || ia.count % 3 || ia.bufferView < 0)
    throw InputError(file, "indices must be unsigned ints, three per triangle");
  const tinygltf::BufferView& iv = m.bufferViews[ia.bufferView];
  if (ia.byteOffset + ia.count * 4 > iv.byteLength || iv.byteOffset + iv.byteLength > m.buffers[iv.buffer].data.size())
    throw InputError(file, "indices: accessor out of its buffer");
  std::vector<std::uint32_t> idx(ia.count);
  std::memcpy(idx.data(), m.buffers[iv.buffer].data.data() + iv.byteOffset + ia.byteOffset, idx.size() * 4);
  for (size_t k = 0; k < idx.size(); k += 3) {
    for (int c = 0; c < 3; ++c)
      if (idx[k + c] >= n) throw InputError(file, "indices: a vertex index out of range");
    s.mesh.faces.push_back({static_cast<int>(idx[k]), static_cast<int>(idx[k + 1]), static_cast<int>(idx[k + 2])});
  }
}

// The texture: its image, and each face's corners' coordinates.
void read_texture(const tinygltf::Model& m, const tinygltf::Primitive& prim, const std::string& file, RiggedSkin* sp) {
  RiggedSkin& s = *sp;
  const size_t n = s.mesh.vertices.size();
  auto attr = [&](const char* name) { return attribute(prim, file, name); };
  const int material = prim.material;
  const int tex = material >= 0 && material < static_cast<int>(m.materials.size())
                      ? m.materials[material].pbrMetallicRoughness.baseColorTexture.index
                      : -1;
  if (tex >= 0) {
    if (tex >= static_cast<int>(m.textures.size()) || m.textures[tex].source < 0 ||
        m.textures[tex].source >= static_cast<int>(m.images.size()))
      throw InputError(file, "the skin's base colour texture names no image");
    const tinygltf::Image& image = m.images[m.textures[tex].source];
    if (image.mimeType != "image/png") throw InputError(file, "the skin's texture must be a PNG (found " + image.mimeType + ")");
    const Rgb8Image rgb = decode_rgb8_png(std::string(image.image.begin(), image.image.end()), file + ": the skin's texture", 8192);
    if (rgb.width != rgb.height) throw InputError(file, "the skin's texture must be square");
    s.texture.size = rgb.width;
    s.texture.rgb = rgb.rgb;
    const std::vector<float> tc = accessor_floats(m, file, attr("TEXCOORD_0"), TINYGLTF_TYPE_VEC2, "TEXCOORD_0");
    if (tc.size() != 2 * n) throw InputError(file, "TEXCOORD_0 and POSITION differ in count");
    for (float f : tc)
      if (f < 0 || f > 1) throw InputError(file, "TEXCOORD_0: a coordinate outside [0, 1]");
    for (const auto& f : s.mesh.faces) {
      std::array<Eigen::Vector2f, 3> c;
      for (int k = 0; k < 3; ++k) c[k] = {tc[2 * f[k]], tc[2 * f[k] + 1]};
      s.texture.corner_uv.push_back(c);
    }
  }
}

// Vertices written once per chart (after the skin's own) go back to their skin vertex.
void merge_seams(const Json& h, const std::string& file, RiggedSkin* sp) {
  RiggedSkin& s = *sp;
  const size_t n = s.mesh.vertices.size();
  if (h.contains("seam_sources")) {
    const Json& seams = h["seam_sources"];
    if (!seams.is_array() || seams.size() > n) throw InputError(file, "extras.handskin.seam_sources must be a list of vertex indices");
    const size_t skin_n = n - seams.size();
    for (size_t k = 0; k < seams.size(); ++k) {
      if (!seams[k].is_number_integer() || seams[k].get<long long>() < 0 || seams[k].get<long long>() >= static_cast<long long>(skin_n))
        throw InputError(file, "extras.handskin.seam_sources[" + std::to_string(k) + "] is not a vertex of the skin");
      const size_t src = seams[k].get<size_t>();
      if (s.mesh.vertices[skin_n + k] != s.mesh.vertices[src])
        throw InputError(file, "seam vertex " + std::to_string(skin_n + k) + " is not a copy of skin vertex " + std::to_string(src));
    }
    for (auto& f : s.mesh.faces)
      for (int& v : f)
        if (static_cast<size_t>(v) >= skin_n) v = seams[static_cast<size_t>(v) - skin_n].get<int>();
    s.mesh.vertices.resize(skin_n);
    s.binding.vertices.resize(skin_n);
  }
}

// The glb as tinygltf reads it (images kept encoded).
tinygltf::Model load_glb(const std::string& file) {
  if (std::error_code ec; !std::filesystem::is_regular_file(file, ec)) throw InputError(file, "no such file");
  tinygltf::Model m;
  tinygltf::TinyGLTF gltf;
  gltf.SetImageLoader(keep_image_bytes, nullptr);
  std::string err, warn;
  if (!gltf.LoadBinaryFromFile(&m, &err, &warn, file)) {
    std::string first = err.substr(0, err.find('\n'));
    throw InputError(file, "not a readable glb: " + (first.empty() ? std::string("unknown error") : first));
  }
  return m;
}

}  // namespace

RiggedSkin read_skin_glb(const std::string& file) {
  const tinygltf::Model m = load_glb(file);
  if (m.scenes.empty()) throw InputError(file, "no scene");
  const Json extras = from_value(m.scenes[m.defaultScene >= 0 ? m.defaultScene : 0].extras);
  if (!extras.contains("handskin") || !extras["handskin"].is_object())
    throw InputError(file, "no handskin extras in its scene: not a skin.glb that handskin wrote");
  const Json& h = extras["handskin"];
  if (!h.contains("format") || h["format"] != kFormat)
    throw InputError(file, std::string("extras.handskin.format must be \"") + kFormat + "\"");
  RiggedSkin s;
  if (!h.contains("rig") || !h.contains("posture_model")) throw InputError(file, "extras.handskin lacks its rig or posture model");
  s.rig = parse_rig(h["rig"].dump(), file + ": extras.handskin.rig");
  s.model = parse_model(h["posture_model"], file + ": extras.handskin.posture_model");
  // The binding's name, as `run` wrote it (the weights themselves are the glb's JOINTS_0 and
  // WEIGHTS_0); absent in a file that lost it: smooth, as `run` makes by default.
  s.binding.mode = "smooth";
  if (h.contains("binding") && !h["binding"].is_null()) {
    if (!h["binding"].is_string() || (h["binding"] != "smooth" && h["binding"] != "rigid"))
      throw InputError(file, "extras.handskin.binding must be \"smooth\" or \"rigid\" (got " + h["binding"].dump() + ")");
    s.binding.mode = h["binding"].get<std::string>();
  }
  const std::array<int, kJointCount> ours = skin_joints(m, file);
  check_bind_matrices(m, file, s.rig, ours);
  const tinygltf::Primitive& prim = skin_primitive(m, file);
  read_vertices(m, prim, file, ours, &s);
  read_triangles(m, prim, file, &s);
  read_texture(m, prim, file, &s);
  merge_seams(h, file, &s);
  return s;
}

}  // namespace handskin
