#include "slamvdb/ontology/ontology.hpp"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/ontology.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

using testing::error_of;
namespace fs = std::filesystem;

const fs::path kFixtureOntology =
    fs::path(SLAMVDB_SOURCE_DIR) / ".." / "shared" / "fixtures" / "rellis3d-000104" / "rellis_ontology.yaml";

TEST(OntologyFile, ShippedCoarseOntologyIsThePapersAndEqualsTheBuiltInTable) {
  const Ontology o = Ontology::load(fs::path(SLAMVDB_SOURCE_DIR) / "data/ontology/rellis3d_coarse.yaml");
  EXPECT_EQ(o.name(), "rellis3d-coarse");
  ASSERT_EQ(o.num_classes(), static_cast<int>(kCoarseClasses.size()));
  for (int k = 0; k < o.num_classes(); ++k) EXPECT_EQ(o.classes()[k].name, kCoarseClasses[k]);
  EXPECT_EQ(o.void_classes(), std::vector<int>{kVoidCoarse});
  EXPECT_EQ(o.void_pixels(), VoidPixels::kTrain);  // the paper trains a Void query
  ASSERT_EQ(o.labels().size(), rellis_classes().size());
  for (std::size_t i = 0; i < o.labels().size(); ++i) {
    const FineClass& c = rellis_classes()[i];
    const OntologyLabel& l = o.labels()[i];
    EXPECT_EQ(l.id, c.id);
    EXPECT_EQ(l.name, c.name);
    EXPECT_EQ(l.rgb, c.rgb) << c.name;
    EXPECT_EQ(l.class_index, c.coarse) << c.name;
  }
  EXPECT_EQ(o.classes()[*o.find_class("bumpy")].name, o.classes()[o.find_label(31)->class_index].name);  // puddle
  EXPECT_EQ(o.classes()[*o.find_class("smooth")].cost, 1.0);
  EXPECT_TRUE(std::isinf(*o.classes()[*o.find_class("obstacle")].cost));
  EXPECT_FALSE(o.classes()[*o.find_class("void")].cost.has_value());
  EXPECT_EQ(o.classes()[0].prompt, "smooth");  // the paper initialises from the class name

  // The compiled-in copy is the same file.
  const Ontology b = Ontology::builtin("rellis3d-coarse");
  EXPECT_EQ(b.class_names(), o.class_names());
  EXPECT_EQ(b.labels().size(), o.labels().size());
}

TEST(OntologyFile, FineOntologyHasEveryRellisClassAsItsOwnClass) {
  const Ontology o = Ontology::load(fs::path(SLAMVDB_SOURCE_DIR) / "data/ontology/rellis3d_fine.yaml");
  EXPECT_EQ(o.name(), "rellis3d-fine");
  ASSERT_EQ(o.num_classes(), static_cast<int>(rellis_classes().size()));
  for (std::size_t i = 0; i < rellis_classes().size(); ++i) {
    const FineClass& c = rellis_classes()[i];
    EXPECT_EQ(o.classes()[i].name, c.name);
    EXPECT_EQ(o.classes()[i].rgb, c.rgb);
    EXPECT_EQ(o.find_label(c.id)->class_index, static_cast<int>(i));
  }
  EXPECT_EQ(o.void_classes(), (std::vector<int>{*o.find_class("void"), *o.find_class("sky")}));
  EXPECT_EQ(Ontology::builtin("rellis3d-fine").num_classes(), o.num_classes());
}

// RELLIS-3D's ontology file says its colours are BGR, but the dataset's own tools write them as
// RGB (utils/label_convert.py, utils/label2color.ipynb), and only as RGB do they make sense: sky
// blue, grass and trees green, dirt and mud brown. Our RGB therefore equals the file's numbers.
TEST(OntologyFile, ColoursAgreeWithTheDatasetsOntologyFile) {
  if (!fs::exists(kFixtureOntology)) GTEST_SKIP() << "fixture missing: " << kFixtureOntology;
  const YAML::Node doc = YAML::LoadFile(kFixtureOntology.string());
  const YAML::Node names = doc["labels"], colours = doc["color_map"];
  ASSERT_EQ(colours.size(), rellis_classes().size());
  const Ontology coarse = Ontology::builtin("rellis3d-coarse");
  for (const FineClass& c : rellis_classes()) {
    ASSERT_TRUE(colours[c.id]) << c.name;
    EXPECT_EQ(names[c.id].as<std::string>(), c.name);
    const auto listed = colours[c.id].as<std::vector<int>>();
    EXPECT_EQ(listed, (std::vector<int>{c.rgb[0], c.rgb[1], c.rgb[2]})) << c.name;
    EXPECT_EQ(coarse.find_label(c.id)->rgb, c.rgb) << c.name;
  }
  const auto rgb = [](std::string_view name) { return find_fine_class(*find_fine_class(name))->rgb; };
  EXPECT_GT(rgb("sky")[2], rgb("sky")[0]);    // blue, not red
  EXPECT_GT(rgb("water")[2], rgb("water")[0]);
  EXPECT_GT(rgb("dirt")[0], rgb("dirt")[2]);  // brown, not blue
  EXPECT_GT(rgb("mud")[0], rgb("mud")[2]);
  EXPECT_GT(rgb("grass")[1], rgb("grass")[0]);
}

TEST(OntologyFile, LabelMappingsForTrainingAndScoring) {
  const Ontology o = Ontology::parse(R"(
name: test
void: [void]
void_pixels: ignore
unlabelled_ids: [255]
classes:
  - {name: ground, rgb: [1, 2, 3], cost: 2}
  - {name: void, rgb: [0, 0, 0]}
labels:
  - {id: 3, name: grass, rgb: [0, 102, 0], class: ground}
  - {id: 7, name: sky, rgb: [0, 0, 255], class: void}
)",
                                     "test.yaml");
  const LabelMapping train = o.training_targets(), truth = o.ground_truth();
  EXPECT_EQ(train(3), 0);
  EXPECT_EQ(train(7), LabelMapping::kIgnore);  // void pixels not trained
  EXPECT_EQ(train(255), LabelMapping::kIgnore);
  EXPECT_EQ(train(4), LabelMapping::kUnknown);
  EXPECT_EQ(train(70000), LabelMapping::kUnknown);
  EXPECT_EQ(truth(7), 1);  // scored as void, which the ConfusionMatrix ignores
  EXPECT_EQ(truth(255), LabelMapping::kIgnore);
  EXPECT_EQ(Ontology::builtin("rellis3d-coarse").training_targets()(7), *Ontology::builtin("rellis3d-coarse").find_class("void"));
}

TEST(OntologyFile, BadFilesAreErrorsNamingFileAndLine) {
  const auto err = [](const std::string& body) {
    return error_of([&] { Ontology::parse(body, "bad.yaml"); });
  };
  const std::string head = "name: t\nclasses:\n  - {name: a, rgb: [1, 2, 3]}\n  - {name: b, rgb: [1, 2, 3]}\n";
  const std::string labels = "labels:\n  - {id: 1, name: x, rgb: [0, 0, 0], class: a}\n  - {id: 2, name: y, rgb: [0, 0, 0], class: b}\n";
  EXPECT_EQ(err(head + labels), "");

  EXPECT_NE(err(head + labels + "  - {id: 1, name: z, rgb: [0, 0, 0], class: a}\n").find("bad.yaml:8: duplicate label id 1"),
            std::string::npos);
  EXPECT_NE(err(head + labels + "  - {id: 5, name: z, rgb: [0, 0, 0], class: c}\n").find("bad.yaml:8: label 'z' names unknown class 'c'"),
            std::string::npos);
  EXPECT_NE(err(head + labels + "  - {id: 5, name: z, rgb: [0, 300, 0], class: a}\n").find("bad.yaml:8: label 'z' rgb channel 300 is out of range"),
            std::string::npos);
  EXPECT_NE(err(head + labels + "  - {id: 5, name: z, rgb: [0, 0], class: a}\n").find("must be [r, g, b]"), std::string::npos);
  EXPECT_NE(err(head + labels + "  - {id: 70000, name: z, rgb: [0, 0, 0], class: a}\n").find("label id 70000 is out of range"),
            std::string::npos);
  EXPECT_NE(err(head + "  - {name: a, rgb: [1, 2, 3]}\n" + labels).find("bad.yaml:5: duplicate class name 'a'"),
            std::string::npos);
  EXPECT_NE(err(head + "  - {name: c, rgb: [1, 2, 3]}\n" + labels).find("class 'c' has no label"), std::string::npos);
  EXPECT_NE(err(head + "  - {name: c, rgb: [1, 2, 3], colour: [1, 2, 3]}\n" + labels).find("unknown key 'colour'"),
            std::string::npos);
  EXPECT_NE(err(head + "  - {name: c, rgb: [1, 2, 3], cost: -1}\n" + labels).find("cost -1 is negative"), std::string::npos);
  EXPECT_NE(err(head + "void: [sky]\n" + labels).find("void class 'sky' is not one of the classes"), std::string::npos);
  EXPECT_NE(err(head + "void: [a, b]\n" + labels).find("every class is void"), std::string::npos);
  EXPECT_NE(err(head + "void_pixels: maybe\n" + labels).find("void_pixels must be 'train' or 'ignore'"), std::string::npos);
  EXPECT_NE(err(head + "unlabelled_ids: [1]\n" + labels).find("label id 1 is also listed in unlabelled_ids"),
            std::string::npos);
  // Names follow the rule of every name shown in tables (core/text_escape.hpp), with the line.
  EXPECT_NE(err(head + "  - {name: \"c\\e[31m\", rgb: [1, 2, 3]}\n" + labels)
                .find("bad.yaml:5: class name 'c\\x1b[31m' holds the control character \\x1b"),
            std::string::npos);
  EXPECT_NE(err(head + "  - {name: \"c\\u202Ed\", rgb: [1, 2, 3]}\n" + labels).find("\\u{202e}"), std::string::npos);
  EXPECT_NE(err(head + labels + "  - {id: 5, name: \"z\\nz\", rgb: [0, 0, 0], class: a}\n")
                .find("bad.yaml:8: label name 'z\\nz' holds the control character \\n"),
            std::string::npos);
  EXPECT_NE(err(head + "  - {name: " + std::string(65, 'c') + ", rgb: [1, 2, 3]}\n" + labels).find("65 bytes"),
            std::string::npos);
  EXPECT_NE(err("name: \"t\\e]0;title\\a\"\n" + head.substr(8) + labels).find("bad.yaml:1: name"), std::string::npos);
  EXPECT_EQ(err("name: t\nclasses:\n  - {name: \"a,b\", rgb: [1, 2, 3]}\n  - {name: \"x|y\", rgb: [1, 2, 3]}\n"
                "labels:\n  - {id: 1, name: x, rgb: [0, 0, 0], class: \"a,b\"}\n"
                "  - {id: 2, name: y, rgb: [0, 0, 0], class: \"x|y\"}\n"),
            "");
  EXPECT_NE(err(head).find("the ontology has no 'labels'"), std::string::npos);
  EXPECT_NE(err("name: t\nclasses: [\n").find("bad.yaml: line"), std::string::npos);
  EXPECT_NE(err("- 1\n- 2\n").find("bad.yaml: is not a YAML mapping"), std::string::npos);

  testing::TempDir dir;
  EXPECT_NE(error_of([&] { Ontology::load(dir.path / "missing.yaml"); }).find("cannot read ontology file"),
            std::string::npos);
  std::ofstream(dir.path / "o.yaml") << head << "  - {name: a, rgb: [1, 2, 3]}\n" << labels;
  EXPECT_NE(error_of([&] { Ontology::load(dir.path / "o.yaml"); }).find((dir.path / "o.yaml").string() + ":5:"),
            std::string::npos);
  EXPECT_NE(error_of([&] { Ontology::load_or_builtin("rellis3d-medium"); }).find("rellis3d-coarse, rellis3d-fine"),
            std::string::npos);
  EXPECT_EQ(Ontology::load_or_builtin("rellis3d-fine").name(), "rellis3d-fine");
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {
// Found by fuzz_ontology: a value of the wrong YAML type escaped as yaml-cpp's TypedBadConversion.
TEST(OntologyFuzzRegression, WrongYamlTypesAreErrorsNamingTheSource) {
  for (const char* yaml : {"name: {a: 1}\nclasses: []\nlabels: []\n", "name: x\nclasses: [[1, 2]]\nlabels: {}\n",
                           "name: x\nclasses:\n  - {name: [a], color: [1, 2, 3]}\nlabels: {}\n"}) {
    try {
      Ontology::parse(yaml, "fuzz.yaml");
      ADD_FAILURE() << "accepted: " << yaml;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("fuzz.yaml"), std::string::npos) << e.what();
    }
  }
}
}  // namespace
}  // namespace slamvdb
