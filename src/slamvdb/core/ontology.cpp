#include "slamvdb/core/ontology.hpp"

namespace slamvdb {

namespace {
enum Coarse { kSmooth = 0, kRough, kBumpy, kObstacle, kActive, kVoid };
}

const std::vector<FineClass>& rellis_classes() {
  // Colours are RGB and equal the numbers of the dataset's ontology file (rellis.yaml,
  // `color_map`). That file's "# bgr" comment is a leftover of the SemanticKITTI configuration it
  // was copied from: the dataset's own tools (utils/label_convert.py, utils/label2color.ipynb) write
  // these numbers as RGB, which gives sky blue, dirt and mud brown and puddles light cyan. Reading
  // them as BGR (as this table once did) paints the sky red. Checked by ontology_test.cpp against
  // the fixture's file.
  static const std::vector<FineClass> classes = {
      {0, "void", {0, 0, 0}, kVoid},             {1, "dirt", {108, 64, 20}, kRough},
      {3, "grass", {0, 102, 0}, kRough},         {4, "tree", {0, 255, 0}, kObstacle},
      {5, "pole", {0, 153, 153}, kObstacle},     {6, "water", {0, 128, 255}, kObstacle},
      {7, "sky", {0, 0, 255}, kVoid},            {8, "vehicle", {255, 255, 0}, kActive},
      {9, "object", {255, 0, 127}, kObstacle},   {10, "asphalt", {64, 64, 64}, kSmooth},
      {12, "building", {255, 0, 0}, kObstacle},  {15, "log", {102, 0, 0}, kObstacle},
      {17, "person", {204, 153, 255}, kActive},  {18, "fence", {102, 0, 204}, kObstacle},
      {19, "bush", {255, 153, 204}, kObstacle},  {23, "concrete", {170, 170, 170}, kSmooth},
      {27, "barrier", {41, 121, 255}, kObstacle},{31, "puddle", {134, 255, 239}, kBumpy},
      {33, "mud", {99, 66, 34}, kBumpy},         {34, "rubble", {110, 22, 138}, kBumpy},
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
