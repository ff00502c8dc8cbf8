#pragma once
// What `slamvdb align` reports (stdout and --json), as library functions: the transform between
// the two maps' worlds (x y z, roll pitch yaw and the matrix), the evidence (candidate, verified,
// consistent and rival pairs, rejections by reason), the uncertainty, the refined overlap and
// RMSE, and the anchors the joint graph moved; or the refusal and its reason.
#include <nlohmann/json.hpp>
#include <string>

#include "slamvdb/sessions/map_alignment.hpp"

namespace slamvdb {

nlohmann::json alignment_report_json(const sessions::MapAlignment& result);
// The same for people (several lines, ending in a newline).
std::string alignment_report_text(const sessions::MapAlignment& result);

}  // namespace slamvdb
