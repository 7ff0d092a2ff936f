#include "pipeline/layout_json.hpp"

#include "core/errors.hpp"

namespace handskin {

Json layout_to_json(const PatchLayout& L) {
  Json v = Json::array(), f = Json::array();
  for (const auto& p : L.vertices) v.push_back(to_json(p));
  for (const auto& c : L.faces) f.push_back({c[0], c[1], c[2], c[3]});
  Json c = Json::array();
  for (const auto& e : L.creases) c.push_back({e[0], e[1]});
  Json out = {{"vertices", v}, {"faces", f}, {"names", L.names}, {"creases", c}};
  if (!L.levels.empty()) {
    Json l = Json::array();
    for (const auto& x : L.levels) l.push_back({x[0], x[1]});
    out["levels"] = l;
  }
  return out;
}

namespace {
constexpr int kMaxLevel = 12;  // halvings of a face along one direction (layout_from_json)
// N vertex indices (a face's corners, a crease's ends) from a JSON array, each in [0, nv).
template <size_t N>
std::array<int, N> vertex_indices(const Json& a, const std::string& where, size_t nv, const std::string& file) {
  if (!a.is_array() || a.size() != N) throw InputError(file, where + " must be " + std::to_string(N) + " vertex indices");
  std::array<int, N> out;
  for (size_t s = 0; s < N; ++s) {
    if (!a[s].is_number_integer() || a[s].get<long>() < 0 || a[s].get<long>() >= static_cast<long>(nv))
      throw InputError(file, where + " must hold vertex indices in [0, " + std::to_string(nv - 1) + "]");
    out[s] = static_cast<int>(a[s].get<long>());
  }
  return out;
}
}  // namespace

PatchLayout layout_from_json(const Json& j, const std::string& file) {
  PatchLayout L;
  const Json& v = require(j, "vertices", file);
  const Json& f = require(j, "faces", file);
  if (!v.is_array() || v.size() < 8 || v.size() > 200000)
    throw InputError(file, "key 'vertices' must be an array of 8 to 200000 points");
  if (!f.is_array() || f.size() < 6 || f.size() > 200000) throw InputError(file, "key 'faces' must be an array of 6 to 200000 faces");
  for (size_t k = 0; k < v.size(); ++k) L.vertices.push_back(to_vec3(v[k], "vertices[" + std::to_string(k) + "]", file));
  for (size_t k = 0; k < f.size(); ++k) L.faces.push_back(vertex_indices<4>(f[k], "faces[" + std::to_string(k) + "]", v.size(), file));
  if (j.contains("names")) {
    const Json& n = j["names"];
    if (!n.is_array() || n.size() != f.size()) throw InputError(file, "key 'names' must name every face");
    for (const auto& s : n) {
      if (!s.is_string()) throw InputError(file, "key 'names' must hold strings");
      L.names.push_back(s.get<std::string>());
    }
  } else {
    for (size_t k = 0; k < f.size(); ++k) L.names.push_back("face" + std::to_string(k));
  }
  if (j.contains("creases")) {
    const Json& c = j["creases"];
    if (!c.is_array()) throw InputError(file, "key 'creases' must be an array of corner pairs");
    for (size_t k = 0; k < c.size(); ++k) L.creases.push_back(vertex_indices<2>(c[k], "creases[" + std::to_string(k) + "]", v.size(), file));
  }
  if (j.contains("levels")) {
    const Json& l = j["levels"];
    if (!l.is_array() || l.size() != f.size()) throw InputError(file, "key 'levels' must give every face its halvings along u and v");
    for (size_t k = 0; k < l.size(); ++k) {
      const std::string where = "levels[" + std::to_string(k) + "]";
      if (!l[k].is_array() || l[k].size() != 2) throw InputError(file, where + " must be two counts");
      std::array<int, 2> x{};
      for (int d = 0; d < 2; ++d) {
        // A face halved 12 times along a direction is 1/4096 of its first length, and grading
        // halves its neighbours nearly as often: no layout within patches.max_patches (20 000).
        // The fit's G1 rows weigh 2^level: every face given 20 more halvings left the normal
        // equations singular to working precision.
        if (!l[k][d].is_number_integer() || l[k][d].get<long>() < 0 || l[k][d].get<long>() > kMaxLevel)
          throw InputError(file, where + " must hold counts in [0, " + std::to_string(kMaxLevel) + "]");
        x[d] = static_cast<int>(l[k][d].get<long>());
      }
      L.levels.push_back(x);
    }
  }
  const LayoutTopology T = layout_topology(L, file);  // closed and oriented alike, or an error naming the edge
  // Graded as a refinement leaves it (balance_cuts): across a border the two faces' halvings
  // across it differ by one at most. The fit weighs C1 there by 2^(their difference): a face
  // given 3 more halvings than its neighbours kinked by 169° at its border, 30 more left the
  // normal equations unsolvable.
  if (!L.levels.empty())
    for (size_t f = 0; f < L.faces.size(); ++f)
      for (int s = 0; s < 4; ++s)
        for (const auto& [g, gs] : T.sides_across(static_cast<int>(f), s)) {
          const int a = L.level(static_cast<int>(f), s % 2 == 0 ? 1 : 0), b = L.level(g, gs % 2 == 0 ? 1 : 0);
          if (a > b + 1)
            throw InputError(file, "levels[" + std::to_string(f) + "] halves face " + std::to_string(f) + " " + std::to_string(a) +
                                       " times across its side " + std::to_string(s) + ", its neighbour there (face " +
                                       std::to_string(g) + ") " + std::to_string(b) +
                                       " times: neighbours differ by one halving at most, as a refinement leaves them");
        }
  // Outward (docs/formats.md: each face counter-clockwise seen from outside): the volume the
  // faces enclose, each as two triangles, positive. A layout turned inside out fits as well,
  // but its patches face into the hand: every normal, the STEP faces and the pictures' light.
  if (layout_volume(L) < 0)
    throw InputError(file, "its faces run clockwise seen from outside (the volume they enclose is negative): each face's "
                           "corners must run counter-clockwise seen from outside");
  return L;
}

PatchLayout parse_patch_layout(const Json& j, const std::string& file) {
  const std::string format = get_string(j, "format", file);
  if (format != "handskin-patches/1" && format != "handskin-patch-layout/1")
    throw InputError(file, "key 'format' must be \"handskin-patches/1\" or \"handskin-patch-layout/1\" (got \"" + format + "\")");
  const Json& layout = require(j, "layout", file);
  if (!layout.is_object()) throw InputError(file, "key 'layout' must be an object");
  return layout_from_json(layout, file + ": layout");
}

}  // namespace handskin
