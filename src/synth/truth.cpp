#include "synth/truth.hpp"

#include "core/transform.hpp"

namespace handskin {

Json truth_to_json(const ScanPair& pair, const Rig& hand_rig, std::uint64_t seed, const ReplicaOptions& replica,
                   const ScannerOptions& scanner, const std::string& skin_file) {
  Json truth;
  truth["format"] = "handskin-truth/1";
  truth["hand"] = hand_side_name(rig_side(hand_rig));
  truth["seed"] = seed;
  truth["back_to_palm"] = isometry_to_json(pair.back_to_palm);
  truth["palm_from_hand"] = isometry_to_json(pair.T_palm_hand);
  truth["back_from_hand"] = isometry_to_json(pair.T_back_hand);
  truth["marker_radius_mm"] = replica.marker_radius_mm;
  Json mp = Json::array(), mb = Json::array(), returns = Json::array();
  for (size_t k = 0; k < pair.markers_hand.size(); ++k) {
    mp.push_back(to_json(pair.T_palm_hand * pair.markers_hand[k]));
    mb.push_back(to_json(pair.T_back_hand * pair.markers_hand[k]));
    auto count = [&](const ScanSimulation& sim) {
      return k + 1 < sim.returns_per_object.size() ? sim.returns_per_object[k + 1] : size_t{0};
    };
    returns.push_back({{"back", static_cast<int>(k) == replica.omit_marker_in_back ? size_t{0} : count(pair.back)},
                       {"palm", count(pair.palm)}});
  }
  truth["markers_palm"] = mp;
  truth["markers_back"] = mb;
  truth["marker_returns"] = returns;
  if (replica.omit_marker_in_back >= 0) truth["marker_omitted_in_back"] = replica.omit_marker_in_back;
  if (pair.extra_bump_hand) truth["extra_bump_back"] = to_json(pair.T_back_hand * *pair.extra_bump_hand);
  truth["skin"] = skin_file;
  truth["scanner"] = {{"laser_tilt_deg", scanner.laser_tilt_deg},
                      {"max_incidence_deg", scanner.max_incidence_deg},
                      {"noise_sigma_mm", scanner.noise_sigma_mm},
                      {"table_height_mm", scanner.table_height_mm},
                      {"table_tilt_deg", scanner.table_tilt_deg}};
  truth["placement_attempts"] = pair.placement_attempts;
  return truth;
}

}  // namespace handskin

namespace handskin {

Json cloud_truth_to_json(const CloudSim& sim, const Rig& hand_rig, std::uint64_t seed, const CloudSimOptions& o,
                         const std::string& skin_file) {
  Json truth;
  truth["format"] = "handskin-truth/1";
  truth["kind"] = "cloud";
  truth["hand"] = hand_side_name(rig_side(hand_rig));
  truth["seed"] = seed;
  truth["back_to_palm"] = isometry_to_json(sim.a_to_b);  // the halves: a (back views) into b (palm views)
  truth["cloud_from_hand"] = isometry_to_json(sim.cloud_from_hand);
  truth["skin"] = skin_file;
  truth["units_per_mm"] = o.units_per_mm;
  truth["scanner"] = {{"views", o.views},
                      {"tilt_deg", o.tilt_deg},
                      {"spacing_mm", o.spacing_mm},
                      {"noise_sigma_mm", o.noise_mm},
                      {"max_incidence_deg", o.max_incidence_deg},
                      {"dropout_from_deg", o.dropout_from_deg},
                      {"stand", o.stand},
                      {"outlier_share", o.outlier_share}};
  truth["points"] = {{"hand", sim.hand_points}, {"stand", sim.stand_points}, {"outliers", sim.outliers},
                     {"dropped_grazing", sim.dropped_grazing}, {"half_a", sim.half_a.size()}, {"half_b", sim.half_b.size()}};
  return truth;
}

}  // namespace handskin
