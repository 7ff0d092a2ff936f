#include "posture/model.hpp"

#include <cstdio>

#include <cmath>
#include <map>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"

namespace handskin {

int require_dof(const std::string& name, const std::string& where) {
  const auto d = dof_index(name);
  if (!d) throw InputError(where, "unknown DOF '" + name + "' (names as in docs/formats.md, e.g. index.mcp.flex or I2.flex)");
  return *d;
}

std::array<DofParams, kDofCount> default_dof_params() {
  std::array<DofParams, kDofCount> p;
  auto set = [&](const std::string& name, double relaxed, double k, double lo, double hi) {
    p[dof_index(name).value()] = DofParams{relaxed, k, lo, hi};
  };
  // The wrist (carpus) carries the whole hand: stiff, so it moves only when driven.
  for (const char* t : {"wrist.tx", "wrist.ty", "wrist.tz"}) set(t, 0, 100, -1000, 1000);
  for (const char* r : {"wrist.rx", "wrist.ry", "wrist.rz"}) set(r, 0, 100, -180, 180);
  // Thumb (Kapandji; AAOS / Greene & Heckman 1994): CMC flexion–extension and palmar
  // abduction, MCP 0–60, IP −15 (hyperextension) to 80.
  set("thumb.cmc.flex", 10, 1, -20, 50);
  set("thumb.cmc.abd", 15, 1, -15, 60);
  set("thumb.mcp.flex", 10, 1, -10, 60);
  set("thumb.mcp.abd", 0, 3, -10, 10);
  set("thumb.ip.flex", 10, 1, -15, 80);
  // Fingers: CMC nearly rigid for index/middle, more mobile toward the little finger (palm
  // cupping); MCP −20..90, PIP 0..110, DIP −5..80 (AAOS; Hume et al. 1990). Relaxed: the
  // resting cascade, flexion growing toward the little finger, DIP ≈ 2/3 PIP.
  struct Row {
    const char* f;
    double cmc_flex, cmc_k, cmc_hi, cmc_abd, mcp, abd_lo, abd_hi, pip, dip;
  };
  const Row rows[] = {{"index", 0, 20, 5, 3, 20, -20, 20, 24, 16},
                      {"middle", 0, 20, 5, 3, 25, -15, 15, 30, 20},
                      {"ring", 2, 6, 10, 5, 30, -15, 20, 33, 22},
                      {"little", 4, 3, 20, 8, 35, -15, 30, 36, 24}};
  for (const Row& r : rows) {
    const std::string f = r.f;
    set(f + ".cmc.flex", r.cmc_flex, r.cmc_k, 0, r.cmc_hi);
    set(f + ".cmc.abd", 0, r.cmc_k, -r.cmc_abd, r.cmc_abd);
    set(f + ".mcp.flex", r.mcp, 1, -20, 90);
    set(f + ".mcp.abd", 0, 3, r.abd_lo, r.abd_hi);
    set(f + ".pip.flex", r.pip, 1, 0, 110);
    set(f + ".dip.flex", r.dip, 1, -5, 80);
  }
  return p;
}

namespace {

// A line through the relaxed posture: θ_b − θ̄_b = slope·(θ_a − θ̄_a), i.e. it constrains the
// departures from rest, not the rest itself.
PairLine relative_line(const std::array<DofParams, kDofCount>& d, const std::string& a, const std::string& b,
                       double slope, double weight, const std::string& source) {
  PairLine l;
  l.a = dof_index(a).value();
  l.b = dof_index(b).value();
  l.alpha = slope;
  l.beta = -1.0;
  l.gamma = -(slope * d[l.a].relaxed - d[l.b].relaxed);
  l.weight = weight;
  l.source = source;
  return l;
}

LinearConstraint parse_constraint(const Json& e, const std::string& where) {
  LinearConstraint c;
  const Json& t = require(e, "terms", where);
  if (!t.is_object() || t.empty()) throw InputError(where, "key 'terms' must be a non-empty object of DOF: coefficient");
  double norm = 0;
  for (auto it = t.begin(); it != t.end(); ++it) {
    const int d = require_dof(it.key(), where + ".terms");
    if (!it.value().is_number() || !(std::abs(it.value().get<double>()) <= kMaxCoefficient))
      throw InputError(where + ".terms." + it.key(), "must be a number within ±" + number_text(kMaxCoefficient));
    c.terms.emplace_back(d, it.value().get<double>());
    norm += std::abs(c.terms.back().second);
  }
  if (norm == 0) throw InputError(where, "every coefficient is zero");
  c.offset = get_finite(e, "offset", where);
  if (!(std::abs(c.offset) <= kMaxOffset)) throw InputError(where, "offset must be within ±" + number_text(kMaxOffset));
  c.weight = get_finite(e, "weight", where);
  if (!(c.weight >= 0 && c.weight <= kMaxWeight))
    throw InputError(where, "weight must be in [0, " + number_text(kMaxWeight) + "] (got " + number_text(c.weight) + ")");
  if (e.contains("source")) c.source = get_string(e, "source", where);
  return c;
}

Json constraint_to_json(const LinearConstraint& c) {
  Json t = Json::object();
  for (const auto& [d, v] : c.terms) t[dofs()[d].name] = v;
  return {{"terms", t}, {"offset", c.offset}, {"weight", c.weight}, {"source", c.source}};
}

}  // namespace

PostureModel component_model(const PostureModel& base, const MixtureComponent& c) {
  PostureModel m = base;
  m.pairs.clear();
  m.grids.clear();
  m.mixture = {};
  m.constraints = c.constraints;
  for (const auto& [d, v] : c.relaxed) m.dof[d].relaxed = v;
  for (const auto& [d, v] : c.stiffness) m.dof[d].stiffness = v;
  return m;
}

PostureModel builtin_model(const std::string& name) {
  PostureModel m;
  m.dof = default_dof_params();
  if (name == "anatomical") {
    m.name = "anatomical";
    m.description =
        "Anatomical defaults: DIP = 2/3 PIP (Rijpkema & Girard 1991), PIP following MCP, neighbouring "
        "fingers' MCPs coupled (enslaving, Hager-Ross & Schieber 2000), thumb IP following its MCP.";
    for (const char* f : {"index", "middle", "ring", "little"}) {
      const std::string s = f;
      m.pairs.push_back(relative_line(m.dof, s + ".pip.flex", s + ".dip.flex", 2.0 / 3.0, 2.0, "DIP-PIP coupling"));
      m.pairs.push_back(relative_line(m.dof, s + ".mcp.flex", s + ".pip.flex", 1.0, 0.3, "PIP follows MCP"));
    }
    m.pairs.push_back(relative_line(m.dof, "index.mcp.flex", "middle.mcp.flex", 1.0, 0.5, "neighbour MCP coupling"));
    m.pairs.push_back(relative_line(m.dof, "middle.mcp.flex", "ring.mcp.flex", 1.0, 1.0, "neighbour MCP coupling"));
    m.pairs.push_back(relative_line(m.dof, "ring.mcp.flex", "little.mcp.flex", 1.0, 1.5, "neighbour MCP coupling"));
    m.pairs.push_back(relative_line(m.dof, "thumb.mcp.flex", "thumb.ip.flex", 0.5, 0.5, "thumb IP follows MCP"));
  } else if (name == "thesis") {
    m.name = "thesis";
    m.description =
        "Thesis Table 3.2, read as theta_first = A * theta_second + b in degrees relative to the relaxed "
        "posture (docs/posture.md); springs K = 1 on every finger DOF.";
    // Subscripts of Table 3.2: 1 CMC, 2 MCP, 3 PIP; P = little finger.
    struct T {
      const char* first;
      const char* second;
      double A, b, W;
    };
    const T table[] = {{"middle.mcp.flex", "ring.mcp.flex", 4.78, -2.01, 0.40},
                       {"ring.cmc.flex", "middle.cmc.flex", 0.58, 0.40, 0.11},
                       {"ring.mcp.flex", "middle.mcp.flex", 0.68, 0.36, 0.50},
                       {"little.mcp.flex", "ring.mcp.flex", 1.58, 0.19, 1.00},
                       {"ring.pip.flex", "index.pip.flex", 1.55, -0.30, 0.67},
                       {"index.mcp.flex", "index.pip.flex", 0.81, -0.12, 0.84}};
    for (const T& t : table) {
      // θ_first − θ̄_first = A (θ_second − θ̄_second) + b  →  absolute line.
      PairLine l = relative_line(m.dof, t.second, t.first, t.A, t.W, "thesis Table 3.2");
      l.gamma += t.b;
      m.pairs.push_back(l);
    }
    for (int d = 6; d < kDofCount; ++d) m.dof[d].stiffness = 1.0;
  } else {
    throw UsageError("--model", "unknown built-in model '" + name + "' (use builtin:anatomical or builtin:thesis)");
  }
  return m;
}

namespace {

void check_weight(double w, const std::string& where) {
  if (!(w >= 0 && w <= kMaxWeight))
    throw InputError(where, "weight must be in [0, " + number_text(kMaxWeight) + "] (got " + number_text(w) + ")");

}

// An optional array of objects under `key`: each entry checked for its keys, then handed on
// with the name that errors use ("<file>: pairs[3]").
template <typename Take>
void each_entry(const Json& j, const std::string& file, const char* key, std::initializer_list<const char*> keys,
                const Take& take) {
  if (!j.contains(key)) return;
  if (!j[key].is_array()) throw InputError(file, std::string("key '") + key + "' must be an array");
  for (size_t k = 0; k < j[key].size(); ++k) {
    const Json& e = j[key][k];
    const std::string entry = std::string(key) + "[" + std::to_string(k) + "]";
    const std::string where = file + ": " + entry;
    if (!e.is_object()) throw InputError(where, "must be an object");
    reject_unknown_keys(e, keys, file, entry);
    take(e, where);
  }

}

// "dofs": each DOF's relaxed angle, stiffness and limits over the defaults.
void parse_dofs(const Json& ds, const std::string& file, PostureModel* m) {
  if (!ds.is_object()) throw InputError(file, "key 'dofs' must be an object keyed by DOF name");
  for (auto it = ds.begin(); it != ds.end(); ++it) {
    const std::string where = file + ": dofs." + it.key();
    const int d = require_dof(it.key(), file + ": dofs");
    if (!it.value().is_object()) throw InputError(where, "must be an object");
    reject_unknown_keys(it.value(), {"relaxed", "stiffness", "limits"}, file, "dofs." + it.key());
    DofParams& p = m->dof[d];
    p.relaxed = get_finite_or(it.value(), "relaxed", p.relaxed, where);
    p.stiffness = get_finite_or(it.value(), "stiffness", p.stiffness, where);
    if (it.value().contains("limits")) {
      const Json& l = it.value()["limits"];
      if (!l.is_array() || l.size() != 2 || !l[0].is_number() || !l[1].is_number())
        throw InputError(where, "key 'limits' must be [low, high]");
      p.lo = l[0].get<double>();
      p.hi = l[1].get<double>();
    }
  }
}

// Every DOF's parameters in range, its relaxed angle within its limits.
void check_dofs(const PostureModel& m, const std::string& file) {
  for (int d = 0; d < kDofCount; ++d) {
    const DofParams& p = m.dof[d];
    const std::string where = file + ": dofs." + dofs()[d].name;
    if (!(p.stiffness >= kMinStiffness && p.stiffness <= kMaxStiffness))
      throw InputError(where, "stiffness must be in [" + number_text(kMinStiffness) + ", " + number_text(kMaxStiffness) +
                                  "] (got " + number_text(p.stiffness) + ")");
    if (!(p.lo < p.hi) || !(std::abs(p.lo) <= kMaxAngle) || !(std::abs(p.hi) <= kMaxAngle))
      throw InputError(where, "limits must be [low, high] with low < high, within ±" + number_text(kMaxAngle));
    if (p.relaxed < p.lo || p.relaxed > p.hi) throw InputError(where, "relaxed angle lies outside the limits");
  }
}

PairLine parse_pair(const Json& e, const std::string& where, bool relative, const PostureModel& m) {
  PairLine l;
  l.a = require_dof(get_string(e, "a", where), where);
  l.b = require_dof(get_string(e, "b", where), where);
  l.alpha = get_finite(e, "alpha", where);
  l.beta = get_finite(e, "beta", where);
  l.gamma = get_finite(e, "gamma", where);
  l.weight = get_finite(e, "weight", where);
  if (e.contains("source")) l.source = get_string(e, "source", where);
  if (l.a == l.b) throw InputError(where, "a pair needs two different DOFs");
  if (l.alpha == 0 && l.beta == 0) throw InputError(where, "alpha and beta are both zero");
  if (!(std::abs(l.alpha) <= kMaxCoefficient && std::abs(l.beta) <= kMaxCoefficient))
    throw InputError(where, "alpha and beta must be within ±" + number_text(kMaxCoefficient));
  if (!(std::abs(l.gamma) <= kMaxOffset)) throw InputError(where, "gamma must be within ±" + number_text(kMaxOffset));
  check_weight(l.weight, where);
  if (relative) l.gamma -= l.alpha * m.dof[l.a].relaxed + l.beta * m.dof[l.b].relaxed;
  return l;
}

PairGrid parse_grid(const Json& e, const std::string& where) {
  PairGrid g;
  g.a = require_dof(get_string(e, "a", where), where);
  g.b = require_dof(get_string(e, "b", where), where);
  g.weight = get_finite(e, "weight", where);
  g.cells = static_cast<int>(get_int(e, "cells", where, 4, 1000));
  auto range = [&](const char* key, double* lo, double* hi) {
    const Json& r = require(e, key, where);
    if (!r.is_array() || r.size() != 2 || !r[0].is_number() || !r[1].is_number() ||
        !(r[0].get<double>() < r[1].get<double>()))
      throw InputError(where, std::string("key '") + key + "' must be [low, high] with low < high");
    *lo = r[0].get<double>();
    *hi = r[1].get<double>();
  };
  range("range_a", &g.lo_a, &g.hi_a);
  range("range_b", &g.lo_b, &g.hi_b);
  const Json& s = require(e, "samples", where);
  if (!s.is_array() || s.empty()) throw InputError(where, "key 'samples' must be a non-empty array of [a, b]");
  for (size_t i = 0; i < s.size(); ++i) {
    if (!s[i].is_array() || s[i].size() != 2 || !s[i][0].is_number() || !s[i][1].is_number() ||
        !std::isfinite(s[i][0].get<double>()) || !std::isfinite(s[i][1].get<double>()))
      throw InputError(where, "samples[" + std::to_string(i) + "] must be [a, b], finite");
    g.samples.push_back({s[i][0].get<double>(), s[i][1].get<double>()});
  }
  if (g.a == g.b) throw InputError(where, "a grid needs two different DOFs");
  check_weight(g.weight, where);
  for (const double v : {g.lo_a, g.hi_a, g.lo_b, g.hi_b})
    if (!(std::abs(v) <= kMaxAngle)) throw InputError(where, "ranges must lie within ±" + number_text(kMaxAngle));
  for (const auto& x : g.samples)
    if (!(std::abs(x[0]) <= kMaxAngle && std::abs(x[1]) <= kMaxAngle))
      throw InputError(where, "samples must lie within ±" + number_text(kMaxAngle));
  // Tables are built by a nearest-sample search per node on load: bound the work.
  if (static_cast<double>(g.cells) * g.cells * static_cast<double>(g.samples.size()) > 2e7)
    throw InputError(where, "grid too large: cells² × samples must stay below 2e7 (e.g. 100 cells, 2000 samples)");
  return g;
}

// One component of "mixture" (its weight added to `total`).
MixtureComponent parse_component(const Json& c, const std::string& cw, const std::string& file, const PostureModel& m,
                                 double* total) {
  MixtureComponent comp;
  comp.weight = get_finite(c, "weight", cw);
  if (!(comp.weight > 0 && comp.weight <= 1)) throw InputError(cw, "weight must be in (0, 1]");
  *total += comp.weight;
  auto per_dof = [&](const char* key, std::vector<std::pair<int, double>>* out) {
    if (!c.contains(key)) return;
    if (!c[key].is_object()) throw InputError(cw, std::string("key '") + key + "' must be an object keyed by DOF name");
    for (auto it = c[key].begin(); it != c[key].end(); ++it) {
      const int d = require_dof(it.key(), cw + "." + key);
      if (!it.value().is_number() || !std::isfinite(it.value().get<double>()))
        throw InputError(cw + "." + key + "." + it.key(), "must be a finite number");
      out->emplace_back(d, it.value().get<double>());
    }
  };
  per_dof("relaxed", &comp.relaxed);
  per_dof("stiffness", &comp.stiffness);
  for (const auto& [d, v] : comp.relaxed)
    if (v < m.dof[d].lo || v > m.dof[d].hi) throw InputError(cw + ".relaxed." + dofs()[d].name, "lies outside the limits");
  for (const auto& [d, v] : comp.stiffness)
    if (!(v >= kMinStiffness && v <= kMaxStiffness))
      throw InputError(cw + ".stiffness." + dofs()[d].name, "must be in [1e-3, 1e3]");
  if (c.contains("constraints")) {
    if (!c["constraints"].is_array() || c["constraints"].size() > static_cast<size_t>(kMaxConstraints))
      throw InputError(cw, "key 'constraints' must be an array of at most " + std::to_string(kMaxConstraints) + " rows");
    for (size_t r = 0; r < c["constraints"].size(); ++r) {
      const std::string rw = cw + ".constraints[" + std::to_string(r) + "]";
      if (!c["constraints"][r].is_object()) throw InputError(rw, "must be an object");
      reject_unknown_keys(c["constraints"][r], {"terms", "offset", "weight", "source"}, file, rw.substr(file.size() + 2));
      comp.constraints.push_back(parse_constraint(c["constraints"][r], rw));
    }
  }
  return comp;
}

// "mixture": the energy scale and the components, whose weights sum to 1.
void parse_mixture(const Json& mx, const std::string& file, PostureModel* mp) {
  PostureModel& m = *mp;
  const std::string where = file + ": mixture";
  if (!mx.is_object()) throw InputError(where, "must be an object");
  reject_unknown_keys(mx, {"energy_scale", "components"}, file, "mixture");
  m.mixture.energy_scale = get_finite(mx, "energy_scale", where);
  if (!(m.mixture.energy_scale >= 1e-6 && m.mixture.energy_scale <= kMaxWeight))
    throw InputError(where, "energy_scale must be in [1e-6, " + number_text(kMaxWeight) + "]");
  const Json& cs = require(mx, "components", where);
  if (!cs.is_array() || cs.empty() || cs.size() > static_cast<size_t>(kMaxMixtureComponents))
    throw InputError(where, "key 'components' must be an array of 1 to " + std::to_string(kMaxMixtureComponents) + " objects");
  double total = 0;
  for (size_t k = 0; k < cs.size(); ++k) {
    const std::string cw = where + ".components[" + std::to_string(k) + "]";
    const Json& c = cs[k];
    if (!c.is_object()) throw InputError(cw, "must be an object");
    reject_unknown_keys(c, {"weight", "relaxed", "stiffness", "constraints"}, file, "mixture.components[" + std::to_string(k) + "]");
    m.mixture.components.push_back(parse_component(c, cw, file, m, &total));
  }
  if (std::abs(total - 1) > 1e-6) throw InputError(where, "the component weights must sum to 1 (got " + number_text(total) + ")");
}

}  // namespace

PostureModel parse_model(const Json& j, const std::string& file) {
  if (get_string(j, "format", file) != "hand-posture/1") throw InputError(file, "key 'format' must be \"hand-posture/1\"");
  reject_unknown_keys(j, {"format", "name", "description", "pair_angles", "dofs", "pairs", "constraints", "grids", "mixture", "notes"},
                      file, "");
  PostureModel m;
  m.dof = default_dof_params();
  if (j.contains("name")) m.name = get_string(j, "name", file);
  if (j.contains("description")) m.description = get_string(j, "description", file);
  bool relative = false;
  if (j.contains("pair_angles")) {
    const std::string pa = get_string(j, "pair_angles", file);
    if (pa != "absolute" && pa != "relative")
      throw InputError(file, "key 'pair_angles' must be \"absolute\" or \"relative\"");
    relative = pa == "relative";
  }
  if (j.contains("dofs")) parse_dofs(j["dofs"], file, &m);
  check_dofs(m, file);
  each_entry(j, file, "pairs", {"a", "b", "alpha", "beta", "gamma", "weight", "source"},
             [&](const Json& e, const std::string& where) { m.pairs.push_back(parse_pair(e, where, relative, m)); });
  each_entry(j, file, "grids", {"a", "b", "weight", "range_a", "range_b", "cells", "samples"},
             [&](const Json& e, const std::string& where) { m.grids.push_back(parse_grid(e, where)); });
  each_entry(j, file, "constraints", {"terms", "offset", "weight", "source"}, [&](const Json& e, const std::string& where) {
    m.constraints.push_back(parse_constraint(e, where));
  });
  if (m.constraints.size() > static_cast<size_t>(kMaxConstraints))
    throw InputError(file, "key 'constraints': at most " + std::to_string(kMaxConstraints) + " rows");
  if (j.contains("mixture")) parse_mixture(j["mixture"], file, &m);
  if (j.contains("notes")) {
    if (!j["notes"].is_array()) throw InputError(file, "key 'notes' must be an array of strings");
    for (const auto& n : j["notes"])
      if (n.is_string()) m.notes.push_back(n.get<std::string>());
  }
  return m;
}

PostureModel load_model(const std::string& file) {
  if (file.rfind("builtin:", 0) == 0) return builtin_model(file.substr(8));
  return parse_model(load_json_object(file), file);
}

Json model_to_json(const PostureModel& m) {
  Json j;
  j["format"] = "hand-posture/1";
  j["name"] = m.name;
  j["description"] = m.description;
  j["pair_angles"] = "absolute";
  Json ds = Json::object();
  for (int d = 0; d < kDofCount; ++d)
    ds[dofs()[d].name] = {{"relaxed", m.dof[d].relaxed}, {"stiffness", m.dof[d].stiffness}, {"limits", {m.dof[d].lo, m.dof[d].hi}}};
  j["dofs"] = ds;
  Json ps = Json::array();
  for (const auto& l : m.pairs)
    ps.push_back({{"a", dofs()[l.a].name}, {"b", dofs()[l.b].name}, {"alpha", l.alpha}, {"beta", l.beta},
                  {"gamma", l.gamma}, {"weight", l.weight}, {"source", l.source}});
  j["pairs"] = ps;
  Json gs = Json::array();
  for (const auto& g : m.grids) {
    Json s = Json::array();
    for (const auto& x : g.samples) s.push_back({std::round(x[0] * 1e3) / 1e3, std::round(x[1] * 1e3) / 1e3});
    gs.push_back({{"a", dofs()[g.a].name}, {"b", dofs()[g.b].name}, {"weight", g.weight}, {"range_a", {g.lo_a, g.hi_a}},
                  {"range_b", {g.lo_b, g.hi_b}}, {"cells", g.cells}, {"samples", s}});
  }
  j["grids"] = gs;
  if (!m.constraints.empty()) {
    Json cs = Json::array();
    for (const auto& c : m.constraints) cs.push_back(constraint_to_json(c));
    j["constraints"] = cs;
  }
  if (!m.mixture.components.empty()) {
    Json comps = Json::array();
    for (const auto& c : m.mixture.components) {
      Json r = Json::object(), k = Json::object(), cs = Json::array();
      for (const auto& [d, v] : c.relaxed) r[dofs()[d].name] = v;
      for (const auto& [d, v] : c.stiffness) k[dofs()[d].name] = v;
      for (const auto& row : c.constraints) cs.push_back(constraint_to_json(row));
      comps.push_back({{"weight", c.weight}, {"relaxed", r}, {"stiffness", k}, {"constraints", cs}});
    }
    j["mixture"] = {{"energy_scale", m.mixture.energy_scale}, {"components", comps}};
  }
  j["notes"] = m.notes;
  return j;
}

void save_model(const std::string& file, const PostureModel& m) { save_json(file, model_to_json(m)); }

}  // namespace handskin
