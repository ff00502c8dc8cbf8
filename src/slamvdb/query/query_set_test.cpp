#include "slamvdb/query/query_set.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <limits>
#include <random>

#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

using testing::error_of;
namespace fs = std::filesystem;

QuerySet random_set(int n, int dim, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  QuerySet q;
  q.model_id = "test-model(dim=" + std::to_string(dim) + ")";
  q.vectors.resize(n, dim);
  for (int k = 0; k < n; ++k) {
    q.names.push_back("class" + std::to_string(k));
    for (int d = 0; d < dim; ++d) q.vectors(k, d) = g(rng);
  }
  return q;
}

void write(const fs::path& file, const std::string& text) { std::ofstream(file, std::ios::binary) << text; }

bool same_bits(const QueryMatrix& a, const QueryMatrix& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(float) * static_cast<std::size_t>(a.size())) == 0;
}

TEST(QuerySet, SaveLoadRoundTripIsBitExact) {
  testing::TempDir dir;
  QuerySet q = random_set(6, 512, 1);
  // Awkward floats: subnormal, extremes, values without a short decimal.
  q.vectors(0, 0) = std::numeric_limits<float>::denorm_min();
  q.vectors(0, 1) = std::numeric_limits<float>::max();
  q.vectors(0, 2) = -std::numeric_limits<float>::min();
  q.vectors(0, 3) = 0.1f;
  q.vectors(0, 4) = 1.f / 3.f;
  q.vectors(0, 5) = -0.f;
  q.colours = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {10, 11, 12}, {13, 14, 15}, {255, 0, 0}};
  q.void_classes = {5};
  q.provenance.method = "train-queries";
  q.provenance.epochs = 2;
  q.provenance.learning_rate = 0.01;
  q.provenance.temperature = 0.07;
  q.provenance.seed = 18446744073709551615ull;
  q.provenance.accuracy = 0.875;
  q.provenance.notes = {{"dataset", "/data/rellis/00001"}, {"init", "text"}};
  save_query_set(dir.path / "q.json", q);
  const QuerySet r = load_query_set(dir.path / "q.json");
  EXPECT_TRUE(same_bits(r.vectors, q.vectors));
  EXPECT_TRUE(std::signbit(r.vectors(0, 5)));
  EXPECT_EQ(r.names, q.names);
  EXPECT_EQ(r.model_id, q.model_id);
  EXPECT_EQ(r.colours, q.colours);
  EXPECT_EQ(r.void_classes, q.void_classes);
  EXPECT_EQ(r.provenance.method, "train-queries");
  EXPECT_EQ(r.provenance.epochs, 2);
  EXPECT_EQ(r.provenance.learning_rate, 0.01);
  EXPECT_EQ(r.provenance.temperature, 0.07);
  EXPECT_EQ(r.provenance.seed, q.provenance.seed);
  EXPECT_EQ(r.provenance.accuracy, 0.875);
  EXPECT_EQ(r.provenance.notes, q.provenance.notes);
  EXPECT_FALSE(fs::exists(dir.path / "q.json.tmp"));
}

TEST(QuerySet, BadFilesAreClearErrors) {
  testing::TempDir dir;
  const fs::path f = dir.path / "q.json";
  EXPECT_NE(error_of([&] { load_query_set(f); }).find("cannot read query set file"), std::string::npos);
  write(f, "{\"format\": \"slamvdb-query-set\", ");
  EXPECT_NE(error_of([&] { load_query_set(f); }).find("is not a JSON query set"), std::string::npos);
  // Numbers beyond double's range make the JSON parser throw out_of_range, not parse_error.
  for (const char* text : {"1e999999", "{\"format\": \"slamvdb-query-set\", \"version\": 2222e2222222222}",
                           "[-1e400]"}) {
    write(f, text);
    EXPECT_NE(error_of([&] { load_query_set(f); }).find("is not a JSON query set"), std::string::npos) << text;
  }
  write(f, "{\"format\": \"something-else\"}");
  EXPECT_NE(error_of([&] { load_query_set(f); }).find("is not a slamvdb query set"), std::string::npos);
  write(f, "{\"format\": 3}");
  EXPECT_NE(error_of([&] { load_query_set(f); }).find("is not a slamvdb query set"), std::string::npos);

  save_query_set(f, random_set(2, 3, 2));
  std::ifstream in(f);
  const std::string good((std::istreambuf_iterator<char>(in)), {});
  const auto edited = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    s.replace(at, from.size(), to);
    write(f, s);
    return error_of([&] { load_query_set(f); });
  };
  EXPECT_NE(edited("\"version\": 1", "\"version\": 2").find("format version 2; this slamvdb reads version 1"),
            std::string::npos);
  EXPECT_NE(edited("\"dim\": 3", "\"dim\": 4").find("class 'class0' has a 3-d vector, the file says dim 4"),
            std::string::npos);
  EXPECT_NE(edited("\"name\": \"class1\"", "\"name\": \"class0\"").find("class name 'class0' appears twice"),
            std::string::npos);
  EXPECT_NE(edited("\"model_id\"", "\"model\"").find("malformed query set"), std::string::npos);
  EXPECT_NE(edited("\"name\": \"class1\"", "\"name\": 7").find("malformed query set"), std::string::npos);

  QuerySet bad = random_set(2, 3, 3);
  bad.vectors(1, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(error_of([&] { save_query_set(f, bad); }).find("class 'class1' has a NaN or infinite value"),
            std::string::npos);
  bad = random_set(2, 3, 3);
  bad.vectors.row(0).setZero();
  EXPECT_NE(error_of([&] { save_query_set(f, bad); }).find("the vector of class 'class0' is zero"), std::string::npos);
  bad = random_set(2, 3, 3);
  bad.void_classes = {0, 1};
  EXPECT_NE(error_of([&] { save_query_set(f, bad); }).find("every class is void"), std::string::npos);
  EXPECT_NE(error_of([&] { save_query_set(dir.path / "no" / "such" / "dir.json", random_set(1, 2, 1)); })
                .find("cannot write"),
            std::string::npos);
}

TEST(QuerySet, CsvFolderImportRoundTrip) {
  testing::TempDir dir;
  const Ontology ontology = Ontology::builtin("rellis3d-coarse");
  QuerySet q = random_set(ontology.num_classes(), 512, 4);
  q = make_query_set(ontology, q.vectors, "lseg-test");
  export_query_csv_dir(q, dir.path / "csv");
  for (const auto& name : ontology.class_names()) EXPECT_TRUE(fs::exists(dir.path / "csv" / (name + ".csv")));

  const QuerySet with = import_query_csv_dir(dir.path / "csv", "lseg-test", &ontology);
  EXPECT_TRUE(same_bits(with.vectors, q.vectors));  // 9 significant digits are exact for float
  EXPECT_EQ(with.names, ontology.class_names());
  EXPECT_EQ(with.colours, q.colours);
  EXPECT_EQ(with.void_classes, std::vector<int>{5});
  EXPECT_EQ(with.provenance.method, "csv-import");

  const QuerySet without = import_query_csv_dir(dir.path / "csv", "lseg-test");  // sorted by name
  EXPECT_EQ(without.names, (std::vector<std::string>{"active", "bumpy", "obstacle", "rough", "smooth", "void"}));
  EXPECT_TRUE(same_bits(QueryMatrix(without.vectors.row(4)), QueryMatrix(q.vectors.row(0))));  // smooth
  EXPECT_TRUE(without.void_classes.empty());
  EXPECT_TRUE(without.colours.empty());

  // The prototype's files: case may differ, whitespace and a trailing newline are fine.
  testing::TempDir proto;
  write(proto.path / "Smooth.csv", " 1.5, -2e-3 ,+3\r\n\n");
  write(proto.path / "rough.CSV", "4,5,6");
  const QuerySet p = import_query_csv_dir(proto.path, "m");
  EXPECT_EQ(p.names, (std::vector<std::string>{"Smooth", "rough"}));
  EXPECT_EQ(p.vectors(0, 0), 1.5f);
  EXPECT_EQ(p.vectors(0, 1), -2e-3f);
  EXPECT_EQ(p.vectors(0, 2), 3.f);
}

TEST(QuerySet, CsvFolderErrorsNameTheFile) {
  testing::TempDir dir;
  const Ontology ontology = Ontology::builtin("rellis3d-coarse");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m"); }).find("no .csv files in"), std::string::npos);
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path / "nope", "m"); }).find("is not a directory"),
            std::string::npos);
  write(dir.path / "a.csv", "1,2,3\n");
  write(dir.path / "b.csv", "1,2\n");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m"); }).find("b.csv has 2 values but"), std::string::npos);
  write(dir.path / "b.csv", "1,x,3\n");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m"); }).find("b.csv:1:3: expected a finite number, got 'x'"),
            std::string::npos);
  write(dir.path / "b.csv", "1,2,3\n4,5,6\n");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m"); }).find("b.csv:2:1: unexpected '4'"), std::string::npos);
  write(dir.path / "b.csv", "1,2,inf\n");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m"); }).find("expected a finite number"), std::string::npos);
  write(dir.path / "b.csv", "1,2,3,\n");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m"); }).find("b.csv:1:7"), std::string::npos);
  fs::remove(dir.path / "b.csv");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m", &ontology); })
                .find("no file for ontology 'rellis3d-coarse' classes: smooth.csv, rough.csv"),
            std::string::npos);
  for (const auto& name : ontology.class_names()) write(dir.path / (name + ".csv"), "1,2,3\n");
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "m", &ontology); }).find("'a.csv' is no class of ontology"),
            std::string::npos);
  fs::remove(dir.path / "a.csv");
  EXPECT_EQ(import_query_csv_dir(dir.path, "m", &ontology).size(), 6);
  EXPECT_NE(error_of([&] { import_query_csv_dir(dir.path, "", &ontology); }).find("no model id"), std::string::npos);
}

TEST(QuerySet, CompatibilityCheckRefusesOtherSpaces) {
  const QuerySet q = random_set(3, 512, 5);
  EXPECT_EQ(error_of([&] { check_compatible(q, 512, q.model_id); }), "");
  const std::string dim = error_of([&] { check_compatible(q, 768, q.model_id); });
  EXPECT_NE(dim.find("the query vectors are 512-d"), std::string::npos) << dim;
  EXPECT_NE(dim.find("map's embeddings are 768-d"), std::string::npos) << dim;
  // The dimension is checked even when the model id check is overridden.
  EXPECT_NE(error_of([&] { check_compatible(q, 768, "other", ModelIdCheck::kIgnore); }), "");
  const std::string model = error_of([&] { check_compatible(q, 512, "conceptfusion"); });
  EXPECT_NE(model.find("belong to model 'test-model(dim=512)' but the map was built with 'conceptfusion'"),
            std::string::npos)
      << model;
  EXPECT_EQ(error_of([&] { check_compatible(q, 512, "conceptfusion", ModelIdCheck::kIgnore); }), "");
}

TEST(QuerySet, OntologyMatchingAndConstruction) {
  const Ontology coarse = Ontology::builtin("rellis3d-coarse"), fine = Ontology::builtin("rellis3d-fine");
  const QuerySet q = make_query_set(coarse, random_set(6, 8, 6).vectors, "m");
  EXPECT_EQ(q.colours[1], coarse.classes()[1].rgb);
  EXPECT_TRUE(q.is_void(5));
  EXPECT_EQ(ontology_classes_of(q, coarse), (std::vector<int>{0, 1, 2, 3, 4, 5}));
  EXPECT_NE(error_of([&] { ontology_classes_of(q, fine); }).find("queries smooth, rough, bumpy, obstacle, active are no class"),
            std::string::npos);
  EXPECT_NE(error_of([&] { make_query_set(coarse, random_set(5, 8, 6).vectors, "m"); }).find("6 class names but 5 vectors"),
            std::string::npos);
}

TEST(QuerySet, CompositeQueryIsTheNormalisedSignedSumOfUnitTerms) {
  const Eigen::Vector3f grass(2, 0, 0), mud(0, 3, 0), sky(0, 0, 0.5f);
  const Eigen::VectorXf v = composite_query({grass, mud}, {sky});
  EXPECT_TRUE(v.isApprox(Eigen::Vector3f(1, 1, -1).normalized()));
  EXPECT_NEAR(v.norm(), 1.f, 1e-6f);
  EXPECT_TRUE(composite_query({grass}, {}).isApprox(Eigen::Vector3f(1, 0, 0)));
  EXPECT_NE(error_of([&] { composite_query({}, {sky}); }).find("at least one positive term"), std::string::npos);
  EXPECT_NE(error_of([&] { composite_query({grass}, {grass}); }).find("cancel out"), std::string::npos);
  EXPECT_NE(error_of([&] { composite_query({grass}, {Eigen::Vector2f(1, 0)}); }).find("negative term 1 is 2-d"),
            std::string::npos);
  EXPECT_NE(error_of([&] { composite_query({grass, Eigen::Vector3f::Zero()}, {}); }).find("positive term 2 is a zero"),
            std::string::npos);
  EXPECT_NE(error_of([&] { composite_query({Eigen::Vector3f(NAN, 0, 0)}, {}); }).find("NaN"), std::string::npos);
}

}  // namespace
}  // namespace slamvdb
