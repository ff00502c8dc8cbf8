#include "slamvdb/io/alignment_report.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/io/map_info_json.hpp"

namespace slamvdb {
namespace {

constexpr double kDegreesPerRadian = 180.0 / M_PI;

nlohmann::json pose_json(const Pose& T) {
  const Vec3d t = T.translation(), rpy = rpy_degrees(T);
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  return {{"x", t.x()}, {"y", t.y()}, {"z", t.z()}, {"roll_deg", rpy.x()}, {"pitch_deg", rpy.y()},
          {"yaw_deg", rpy.z()}, {"matrix", rows}};
}

}  // namespace

nlohmann::json alignment_report_json(const sessions::MapAlignment& result) {
  const sessions::SessionAlignment& a = result.alignment;
  nlohmann::json rejections = nlohmann::json::object();
  for (std::size_t r = 0; r < a.rejections.size(); ++r)
    rejections[sessions::to_string(static_cast<sessions::PairRejection>(r))] = a.rejections[r];
  nlohmann::json pairs = nlohmann::json::array();
  for (std::size_t i = 0; i < a.verified.size(); ++i) {
    const sessions::VerifiedPair& p = a.verified[i];
    const bool consistent = std::find(a.consistent.begin(), a.consistent.end(), i) != a.consistent.end();
    pairs.push_back({{"base_submap", p.base_submap_id}, {"other_submap", p.other_submap_id},
                     {"other_place", {p.other_place_world.x(), p.other_place_world.y(), p.other_place_world.z()}},
                     {"descriptor_distance", p.descriptor_distance}, {"overlap", p.overlap}, {"rmse", p.rmse},
                     {"structure_overlap", p.structure_overlap}, {"consistent", consistent},
                     {"T_base_other", pose_json(p.T_base_other)}});
  }
  nlohmann::json j = {{"aligned", a.aligned},
                      {"base_places", a.base_places},
                      {"other_places", a.other_places},
                      {"candidate_pairs", a.candidate_pairs},
                      {"surveyed_places", a.surveyed_places},
                      {"guided_pairs", a.guided_pairs},
                      {"verified_pairs", a.verified.size()},
                      {"consistent_pairs", a.consistent.size()},
                      {"rival_pairs", a.rival_pairs},
                      {"rejections", rejections},
                      {"pairs", pairs}};
  if (!a.aligned) {
    j["refused"] = a.refused;
    return j;
  }
  j["T_base_other"] = pose_json(a.T_base_other);
  j["uncertainty"] = {{"translation_m", a.sigma_translation}, {"rotation_deg", a.sigma_rotation * kDegreesPerRadian}};
  j["refined"] = {{"overlap", a.overlap}, {"rmse_m", a.rmse}};
  nlohmann::json anchors = nlohmann::json::array();
  for (const auto& [id, after] : result.anchors_after) {
    const Pose rigid = a.T_base_other * result.anchors_before.at(id);
    anchors.push_back({{"submap", id},
                       {"T_base_submap", pose_json(after)},
                       {"graph_correction_m", (after.translation() - rigid.translation()).norm()}});
  }
  j["anchors"] = anchors;
  if (!result.base_anchors_after.empty()) {  // --adjust-base
    nlohmann::json base = nlohmann::json::array();
    for (const auto& [id, after] : result.base_anchors_after)
      base.push_back({{"submap", id},
                      {"T_base_submap", pose_json(after)},
                      {"graph_correction_m", (after.translation() - result.base_anchors_before.at(id).translation()).norm()}});
    j["base_anchors"] = base;
  }
  return j;
}

std::string alignment_report_text(const sessions::MapAlignment& result) {
  const sessions::SessionAlignment& a = result.alignment;
  std::string out = fmt::format("places       {} base, {} other; {} candidate pairs, {} verified, {} consistent, "
                                "rival set {}\n",
                                a.base_places, a.other_places, a.candidate_pairs, a.verified.size(), a.consistent.size(),
                                a.rival_pairs);
  if (a.surveyed_places > 0)
    out += fmt::format("survey       {} places decided; {} pairs verified guided by its alignment\n", a.surveyed_places,
                       a.guided_pairs);
  std::string rejected;
  for (std::size_t r = 0; r < a.rejections.size(); ++r)
    if (a.rejections[r])
      rejected += fmt::format("{}{} {}", rejected.empty() ? "" : ", ", a.rejections[r],
                              sessions::to_string(static_cast<sessions::PairRejection>(r)));
  if (!rejected.empty()) out += fmt::format("rejected     {}\n", rejected);
  if (!a.aligned) return out + fmt::format("refused      {}\n", a.refused);
  const Pose& T = a.T_base_other;
  const Vec3d t = T.translation(), rpy = rpy_degrees(T);
  out += fmt::format("T_base_other x y z = ({:.3f}, {:.3f}, {:.3f}) m, roll pitch yaw = ({:.3f}, {:.3f}, {:.3f}) deg\n",
                     t.x(), t.y(), t.z(), rpy.x(), rpy.y(), rpy.z());
  for (int r = 0; r < 4; ++r)
    out += fmt::format("  [{:10.6f} {:10.6f} {:10.6f} {:10.3f}]\n", T(r, 0), T(r, 1), T(r, 2), T(r, 3));
  out += fmt::format("uncertainty  {:.3f} m, {:.4f} deg (standard error over the consistent pairs)\n",
                     a.sigma_translation, a.sigma_rotation * kDegreesPerRadian);
  out += fmt::format("refined      overlap {:.3f}, RMSE {:.3f} m\n", a.overlap, a.rmse);
  double largest = 0.0;
  for (const auto& [id, after] : result.anchors_after)
    largest = std::max(largest, (after.translation() - (T * result.anchors_before.at(id)).translation()).norm());
  out += fmt::format("anchors      {} submaps moved into the base's world; the joint graph corrected them by up to "
                     "{:.3f} m beyond the rigid transform\n",
                     result.anchors_after.size(), largest);
  if (!result.base_anchors_after.empty()) {  // --adjust-base
    double moved = 0.0;
    for (const auto& [id, after] : result.base_anchors_after)
      moved = std::max(moved, (after.translation() - result.base_anchors_before.at(id).translation()).norm());
    out += fmt::format("base anchors {} submaps adjusted by the joint graph (the first held), by up to {:.3f} m\n",
                       result.base_anchors_after.size(), moved);
  }
  return out;
}

}  // namespace slamvdb
