#include "slamvdb/core/ontology.hpp"

namespace slamvdb {

namespace {
enum Coarse { kSmooth = 0, kRough, kBumpy, kObstacle, kActive, kVoid };
}

const std::vector<FineClass>& rellis_classes() {
  // Colours are RGB (the dataset's ontology file lists them as BGR).
  static const std::vector<FineClass> classes = {
      {0, "void", {0, 0, 0}, kVoid},           {1, "dirt", {20, 64, 108}, kRough},
      {3, "grass", {0, 102, 0}, kRough},       {4, "tree", {0, 255, 0}, kObstacle},
      {5, "pole", {153, 153, 0}, kObstacle},   {6, "water", {255, 128, 0}, kObstacle},
      {7, "sky", {255, 0, 0}, kVoid},          {8, "vehicle", {0, 255, 255}, kActive},
      {9, "object", {127, 0, 255}, kObstacle}, {10, "asphalt", {64, 64, 64}, kSmooth},
      {12, "building", {0, 0, 255}, kObstacle},{15, "log", {0, 0, 102}, kObstacle},
      {17, "person", {255, 153, 204}, kActive},{18, "fence", {204, 0, 102}, kObstacle},
      {19, "bush", {204, 153, 255}, kObstacle},{23, "concrete", {170, 170, 170}, kSmooth},
      {27, "barrier", {255, 121, 41}, kObstacle},{31, "puddle", {239, 255, 134}, kBumpy},
      {33, "mud", {34, 66, 99}, kBumpy},       {34, "rubble", {138, 22, 110}, kBumpy},
  };
  return classes;
}

const FineClass* find_fine_class(uint16_t id) {
  for (const auto& c : rellis_classes())
    if (c.id == id) return &c;
  return nullptr;
}

std::optional<uint16_t> find_fine_class(std::string_view name) {
  for (const auto& c : rellis_classes())
    if (c.name == name) return c.id;
  return std::nullopt;
}

int coarse_of(uint16_t fine_id) {
  const FineClass* c = find_fine_class(fine_id);
  return c ? c->coarse : kVoid;
}

}  // namespace slamvdb
