#include "slamvdb/eval/confusion_matrix.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "slamvdb/eval/pixel_scoring.hpp"
#include "slamvdb/testing/csv_reader.hpp"
#include "slamvdb/testing/error_of.hpp"

namespace slamvdb {
namespace {

// Hand-worked example; void (3) is ignored.
//   truth \ predicted   smooth rough obstacle void none
//   smooth                 3     1      0      0    0     relevant 4
//   rough                  1     6      2      0    1     relevant 10
//   obstacle               0     2      8      2    0     relevant 12
//   void                   0     5      0      0    0     ignored 5
//   recalled               4     9     10
ConfusionMatrix example() {
  ConfusionMatrix m({"smooth", "rough", "obstacle", "void"}, {3});
  m.add(0, 0, 3);
  m.add(0, 1);
  m.add(1, 1, 6);
  m.add(1, 0);
  m.add(1, 2, 2);
  m.add(1, ConfusionMatrix::kNoPrediction);
  m.add(2, 2, 8);
  m.add(2, 1, 2);
  m.add(2, 3, 2);
  m.add(3, 1, 5);
  return m;
}

TEST(ConfusionMatrix, HandWorkedScores) {
  const ConfusionMatrix m = example();
  EXPECT_EQ(m.relevant(0), 4u);
  EXPECT_EQ(m.relevant(1), 10u);
  EXPECT_EQ(m.relevant(2), 12u);
  EXPECT_EQ(m.recalled(0), 4u);
  EXPECT_EQ(m.recalled(1), 9u);  // the 5 void elements predicted rough are not scored
  EXPECT_EQ(m.recalled(2), 10u);
  EXPECT_EQ(m.scored(), 26u);
  EXPECT_EQ(m.ignored(), 5u);
  EXPECT_DOUBLE_EQ(*m.recall(0), 0.75);
  EXPECT_DOUBLE_EQ(*m.recall(1), 0.6);
  EXPECT_DOUBLE_EQ(*m.recall(2), 8.0 / 12.0);
  EXPECT_DOUBLE_EQ(*m.precision(1), 6.0 / 9.0);
  EXPECT_DOUBLE_EQ(*m.precision(2), 0.8);
  EXPECT_DOUBLE_EQ(*m.iou(0), 3.0 / 5.0);
  EXPECT_DOUBLE_EQ(*m.iou(1), 6.0 / 13.0);
  EXPECT_DOUBLE_EQ(*m.iou(2), 8.0 / 14.0);
  EXPECT_DOUBLE_EQ(*m.accuracy(), 17.0 / 26.0);
  EXPECT_DOUBLE_EQ(*m.mean_iou(), (3.0 / 5.0 + 6.0 / 13.0 + 8.0 / 14.0) / 3.0);

  const MetricsReport r = m.report();
  ASSERT_EQ(r.classes.size(), 3u);  // void is not reported
  EXPECT_EQ(r.classes[2].name, "obstacle");
  EXPECT_EQ(r.unpredicted, 1u);
  EXPECT_EQ(r.ignored_classes, std::vector<std::string>{"void"});
}

TEST(ConfusionMatrix, UndefinedScoresAreEmptyNotNaN) {
  ConfusionMatrix m({"a", "b"});
  EXPECT_FALSE(m.accuracy());
  EXPECT_FALSE(m.mean_iou());
  m.add(0, 0, 2);
  EXPECT_FALSE(m.recall(1));     // no b in the ground truth
  EXPECT_FALSE(m.precision(1));  // never predicted
  EXPECT_FALSE(m.iou(1));
  EXPECT_DOUBLE_EQ(*m.mean_iou(), 1.0);  // over the classes with a defined IoU
  m.add(0, 1);
  EXPECT_DOUBLE_EQ(*m.precision(1), 0.0);
  EXPECT_DOUBLE_EQ(*m.iou(1), 0.0);
}

TEST(ConfusionMatrix, TablesInThePapersForm) {
  MetricsReport r = example().report();
  r.hit_rate = 0.8126;
  r.classes[1].hit = 0.7557;
  const std::string md = to_markdown(r);
  EXPECT_NE(md.find("| Class | Hit % | Recall % | Prec. % | IoU % | Recalled (x1000) | Relevant (x1000) |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| *all* | 81.26 | 65.38 |  |  | 0.03 | 0.03 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| *smooth* |  | 75.00 | 75.00 | 60.00 | 0.00 | 0.00 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| *rough* | 75.57 | 60.00 | 66.67 | 46.15 | 0.01 | 0.01 |"), std::string::npos) << md;
  EXPECT_NE(md.find("mIoU 54.43 %"), std::string::npos) << md;
  EXPECT_NE(md.find("Ignored: void (5 elements)"), std::string::npos) << md;

  const auto j = nlohmann::json::parse(to_json(r));
  EXPECT_DOUBLE_EQ(j["accuracy"].get<double>(), 17.0 / 26.0);
  EXPECT_DOUBLE_EQ(j["hit_rate"].get<double>(), 0.8126);
  EXPECT_DOUBLE_EQ(j["classes"]["obstacle"]["precision"].get<double>(), 0.8);
  EXPECT_EQ(j["classes"]["obstacle"]["recalled"].get<int>(), 10);
  EXPECT_EQ(j["classes"]["obstacle"]["relevant"].get<int>(), 12);
  EXPECT_FALSE(j["classes"]["obstacle"].contains("hit"));
  EXPECT_DOUBLE_EQ(j["classes"]["rough"]["hit"].get<double>(), 0.7557);
  EXPECT_FALSE(j["classes"].contains("void"));
  EXPECT_EQ(j["ignored"].get<int>(), 5);

  const std::string csv = to_csv(r);
  EXPECT_EQ(csv.substr(0, csv.find('\n')), "class,hit,recall,precision,iou,recalled,relevant");
  EXPECT_NE(csv.find("\nall,0.812600,0.653846,,,26,26\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\nsmooth,,0.750000,0.750000,0.600000,4,4\n"), std::string::npos) << csv;

  ConfusionMatrix odd({"a,b", "c"});
  odd.add(0, 0);
  EXPECT_NE(to_csv(odd.report()).find("\n\"a,b\","), std::string::npos);
  // Names with CSV and markdown syntax stay one field / one cell (CSV read back strictly, RFC 4180).
  const std::vector<std::string> hostile = {"a,b", "say \"hi\"", "x|y", "two\nlines", "*bold*"};
  ConfusionMatrix m(hostile);
  for (int k = 0; k < 5; ++k) m.add(k, k);
  const auto records = testing::read_csv_strict(to_csv(m.report()));
  ASSERT_TRUE(records);
  ASSERT_EQ(records->size(), 2u + hostile.size());
  for (std::size_t k = 0; k < hostile.size(); ++k) {
    EXPECT_EQ((*records)[k + 2].size(), 7u);
    EXPECT_EQ((*records)[k + 2][0], hostile[k]);
  }
  const std::string table = to_markdown(m.report());
  std::size_t rows = 0;
  for (std::size_t start = 0, end; (end = table.find('\n', start)) != std::string::npos; start = end + 1) {
    const std::string line = table.substr(start, end - start);
    if (line.empty() || line[0] != '|') continue;
    ++rows;
    std::size_t cells = 0;
    for (std::size_t i = 0; i < line.size(); ++i) cells += line[i] == '|' && (i == 0 || line[i - 1] != '\\');
    EXPECT_EQ(cells, 8u) << line;
  }
  EXPECT_EQ(rows, 3u + hostile.size());  // header, rule, all, one per class
  EXPECT_NE(table.find("| *x\\|y* |"), std::string::npos) << table;
  EXPECT_NE(to_json(ConfusionMatrix({"a"}).report()).find("\"accuracy\": null"), std::string::npos);
}

TEST(ConfusionMatrix, MergeAndErrors) {
  ConfusionMatrix a = example(), b = example();
  a.merge(b);
  EXPECT_EQ(a.scored(), 52u);
  EXPECT_EQ(a.ignored(), 10u);
  EXPECT_DOUBLE_EQ(*a.accuracy(), 17.0 / 26.0);
  EXPECT_THROW(a.merge(ConfusionMatrix({"smooth", "rough", "obstacle", "void"})), Error);
  EXPECT_NE(testing::error_of([&] { a.add(4, 0); }).find("ground-truth class 4 is out of range"), std::string::npos);
  EXPECT_NE(testing::error_of([&] { a.add(0, -2); }).find("predicted class -2"), std::string::npos);
  EXPECT_THROW(ConfusionMatrix({}), Error);
  EXPECT_THROW(ConfusionMatrix({"a", "a"}), Error);
  EXPECT_THROW(ConfusionMatrix({"a"}, {1}), Error);
}

TEST(PixelScoring, FeatureMapAgainstLabelsWithTheVoidRule) {
  const Ontology o = Ontology::parse(R"(
name: t
void: [void]
unlabelled_ids: [255]
classes:
  - {name: ground, rgb: [0, 0, 0]}
  - {name: tree, rgb: [0, 0, 0]}
  - {name: void, rgb: [0, 0, 0]}
labels:
  - {id: 3, name: grass, rgb: [0, 0, 0], class: ground}
  - {id: 4, name: tree, rgb: [0, 0, 0], class: tree}
  - {id: 7, name: sky, rgb: [0, 0, 0], class: void}
)",
                                     "t.yaml");
  // Queries in the order tree, ground, void: the mapping to ontology classes is by name.
  QuerySet q;
  q.model_id = "m";
  q.names = {"tree", "ground", "void"};
  q.vectors = QueryMatrix::Identity(3, 3);
  q.void_classes = {2};
  FeatureMap f(3, 1, 5);
  const float pixels[5][3] = {{0, 1, 0}, {1, 0.2f, 0}, {0.1f, 0.3f, 1}, {0, 0, 0}, {1, 0, 0}};
  for (int x = 0; x < 5; ++x) std::copy(pixels[x], pixels[x] + 3, f.pixel(x, 0));
  // grass -> ground (right); tree -> tree (right); grass, void best -> ground (right);
  // tree with a zero feature -> no prediction; unlabelled -> skipped.
  const std::vector<uint16_t> labels = {3, 4, 3, 4, 255};
  ConfusionMatrix m = ontology_confusion_matrix(o);
  const PixelCounts c = score_feature_map(f, labels, o.ground_truth(), QueryClassifier(q), ontology_classes_of(q, o),
                                          m, "frame 1");
  EXPECT_EQ(c.pixels, 4u);
  EXPECT_EQ(c.unlabelled, 1u);
  EXPECT_EQ(m.count(0, 0), 2u);
  EXPECT_EQ(m.count(1, 1), 1u);
  EXPECT_EQ(m.count(1, ConfusionMatrix::kNoPrediction), 1u);
  EXPECT_DOUBLE_EQ(*m.accuracy(), 0.75);

  const std::vector<uint16_t> unknown = {3, 4, 9, 4, 3};
  EXPECT_NE(testing::error_of([&] {
              score_feature_map(f, unknown, o.ground_truth(), QueryClassifier(q), ontology_classes_of(q, o), m, "frame 2");
            }).find("frame 2: label id 9 at pixel (2, 0)"),
            std::string::npos);
  EXPECT_NE(testing::error_of([&] {
              score_feature_map(f, std::vector<uint16_t>(4), o.ground_truth(), QueryClassifier(q),
                                ontology_classes_of(q, o), m, "frame 3");
            }).find("4 labels for a 5 x 1 feature map"),
            std::string::npos);
}

}  // namespace
}  // namespace slamvdb
