#include "slamvdb/core/ontology.hpp"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

namespace slamvdb {
namespace {

TEST(Ontology, BuiltInTableEqualsTheOntologyFile) {
  const YAML::Node doc = YAML::LoadFile(std::string(SLAMVDB_SOURCE_DIR) + "/data/ontology/rellis3d_coarse.yaml");
  const YAML::Node coarse = doc["classes"];
  ASSERT_EQ(coarse.size(), kCoarseClasses.size());
  for (std::size_t i = 0; i < coarse.size(); ++i) EXPECT_EQ(coarse[i]["name"].as<std::string>(), kCoarseClasses[i]);
  const YAML::Node classes = doc["labels"];
  ASSERT_EQ(classes.size(), rellis_classes().size());
  for (std::size_t i = 0; i < classes.size(); ++i) {
    const FineClass& c = rellis_classes()[i];
    EXPECT_EQ(classes[i]["id"].as<int>(), c.id);
    EXPECT_EQ(classes[i]["name"].as<std::string>(), c.name);
    const auto rgb = classes[i]["rgb"].as<std::vector<int>>();
    EXPECT_EQ(rgb, (std::vector<int>{c.rgb[0], c.rgb[1], c.rgb[2]})) << c.name;
    EXPECT_EQ(classes[i]["class"].as<std::string>(), kCoarseClasses[c.coarse]) << c.name;
  }
}

TEST(Ontology, PaperGroupsAndLookups) {
  EXPECT_EQ(kCoarseClasses[coarse_of(*find_fine_class("asphalt"))], "smooth");
  EXPECT_EQ(kCoarseClasses[coarse_of(*find_fine_class("grass"))], "rough");
  EXPECT_EQ(kCoarseClasses[coarse_of(*find_fine_class("mud"))], "bumpy");
  EXPECT_EQ(kCoarseClasses[coarse_of(*find_fine_class("fence"))], "obstacle");
  EXPECT_EQ(kCoarseClasses[coarse_of(*find_fine_class("person"))], "active");
  EXPECT_EQ(kCoarseClasses[coarse_of(*find_fine_class("sky"))], "void");
  EXPECT_EQ(coarse_of(999), kVoidCoarse);
  EXPECT_EQ(find_fine_class(uint16_t{2}), nullptr);
  EXPECT_FALSE(find_fine_class("lava").has_value());
}

}  // namespace
}  // namespace slamvdb
