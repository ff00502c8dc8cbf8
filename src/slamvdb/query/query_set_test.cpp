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

TEST(QuerySet, ClassNamesAreBoundedWhereverASetComesFrom) {
  testing::TempDir dir;
  const fs::path f = dir.path / "q.json";
  // Commas, quotes and pipes are names like any other (the CSV writer quotes them).
  QuerySet q = random_set(3, 4, 5);
  q.names = {"a,b", "say \"hi\"", "x|y"};
  save_query_set(f, q);
  EXPECT_EQ(load_query_set(f).names, q.names);
  // Control characters (ANSI escapes, a right-to-left override, a line break), bad UTF-8 and long
  // names are refused when the file is loaded, naming the file and the class, the name escaped.
  std::ifstream in(f);
  const std::string good((std::istreambuf_iterator<char>(in)), {});
  for (const auto& [json_name, mention] : std::vector<std::pair<std::string, std::string>>{
           {"red\\u001b[31m", "'red\\x1b[31m' holds the control character \\x1b"},
           {"abc\\u202efdp", "\\u{202e}"},
           {"two\\nlines", "'two\\nlines' holds the control character \\n"},
           {std::string(65, 'n'), "65 bytes long; at most 64"},
           {" padded", "space"}}) {
    std::string text = good;
    text.replace(text.find("\"x|y\""), 5, "\"" + json_name + "\"");
    write(f, text);
    const std::string error = error_of([&] { load_query_set(f); });
    EXPECT_NE(error.find(f.string() + ": the name of class 3 "), std::string::npos) << error;
    EXPECT_NE(error.find(mention), std::string::npos) << error;
    EXPECT_EQ(error.find('\x1b'), std::string::npos) << error;
    EXPECT_EQ(error.find("\xe2\x80\xae"), std::string::npos) << error;
  }
  // The same rule for a set made by a program, and for class names taken from CSV file names.
  q.names[0] = "tab\tname";
  EXPECT_NE(error_of([&] { save_query_set(f, q); }).find("control character \\t"), std::string::npos);
  const fs::path csv_dir = dir.path / "csv";
  fs::create_directories(csv_dir);
  write(csv_dir / "grass.csv", "1,0\n");
  write(csv_dir / "mud\x1b[2J.csv", "0,1\n");
  EXPECT_NE(error_of([&] { import_query_csv_dir(csv_dir, "m"); }).find("control character \\x1b"), std::string::npos);
}

TEST(QuerySet, HugeAndTinyFiniteTermsKeepTheirDirection) {
  // Before: a 1e30 vector's float sum of squares overflowed, and the query was reported as
  // "terms cancel out: zero vector"; below ~1e-19 it underflowed to a "zero" vector.
  const Eigen::Vector3f direction = Eigen::Vector3f(1, 2, -2) / 3;
  for (const float scale : {1e30f, 3e38f / 2, 1e-30f, 1e-42f /* subnormal */}) {
    const Eigen::Vector3f term = Eigen::Vector3f(1, 2, -2) * scale;
    ASSERT_TRUE(term.allFinite()) << scale;
    const auto unit = unit_vector({term.data(), 3});
    ASSERT_TRUE(unit) << scale;
    EXPECT_TRUE(unit->isApprox(direction, 1e-5f)) << scale << " " << unit->transpose();
    EXPECT_TRUE(composite_query({term}, {}).isApprox(direction, 1e-5f)) << scale;
  }
  EXPECT_TRUE(composite_query({Eigen::Vector3f(1e30f, 0, 0)}, {Eigen::Vector3f(0, 1e-30f, 0)})
                  .isApprox(Eigen::Vector3f(1, -1, 0).normalized()));
  const float zero[3] = {0, 0, 0}, inf[3] = {0, std::numeric_limits<float>::infinity(), 0};
  EXPECT_FALSE(unit_vector(zero));
  EXPECT_FALSE(unit_vector(inf));
  // Query sets: tiny rows are not "zero".
  QuerySet q = random_set(2, 3, 9);
  q.vectors *= 1e-30f;
  EXPECT_NO_THROW(q.validate("tiny"));
}

}  // namespace
}  // namespace slamvdb
