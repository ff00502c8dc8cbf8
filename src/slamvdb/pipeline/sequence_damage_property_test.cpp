// Property: whatever damage is done to the files of a valid sequence (truncation, bit flips, swapped
// fields, extreme numbers, swapped files), `slamvdb map` on it never crashes (exit code 0, 1 or 2,
// never a signal), never hangs, and every map it writes loads and holds only finite values.
// Deterministic: case i uses seed i. SLAMVDB_DAMAGE_CASES=N runs more cases (default 24, ~30 s).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <cstdlib>
#include <fstream>
#include <future>
#include <iterator>
#include <random>

#include "slamvdb/store/map_store.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/map_checks.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using Rng = std::mt19937_64;

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
void write_bytes(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }

std::size_t uniform(Rng& rng, std::size_t n) { return n ? std::uniform_int_distribution<std::size_t>(0, n - 1)(rng) : 0; }

bool is_text(const fs::path& p) { return p.extension() == ".txt" || p.extension() == ".yaml"; }

// Whitespace-separated tokens of a text: (offset, length).
std::vector<std::pair<std::size_t, std::size_t>> tokens(const std::string& text) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t i = 0; i < text.size();) {
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    const std::size_t start = i;
    while (i < text.size() && !std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    if (i > start) out.emplace_back(start, i - start);
  }
  return out;
}

// One random damage to one file (or two); returns what was done, for the failure message.
std::string damage(const std::vector<fs::path>& files, Rng& rng) {
  const fs::path& file = files[uniform(rng, files.size())];
  std::string bytes = read_bytes(file);
  const std::string name = file.filename().string();
  switch (uniform(rng, 5)) {
    case 0: {  // truncation
      const std::size_t size = uniform(rng, bytes.size());
      bytes.resize(size);
      write_bytes(file, bytes);
      return fmt::format("truncated {} to {} bytes", name, size);
    }
    case 1: {  // bit flips
      const std::size_t flips = 1 + uniform(rng, 8);
      for (std::size_t i = 0; i < flips && !bytes.empty(); ++i) bytes[uniform(rng, bytes.size())] ^= char(1 << uniform(rng, 8));
      write_bytes(file, bytes);
      return fmt::format("flipped {} bits in {}", flips, name);
    }
    case 2: {  // swapped fields: two tokens of a text file, two 4-byte words of a binary one
      if (is_text(file)) {
        auto t = tokens(bytes);
        if (t.size() < 2) return "nothing to swap in " + name;
        auto a = t[uniform(rng, t.size())], b = t[uniform(rng, t.size())];
        if (a.first > b.first) std::swap(a, b);
        if (a.first == b.first) return "same field twice in " + name;
        const std::string ta = bytes.substr(a.first, a.second), tb = bytes.substr(b.first, b.second);
        bytes.replace(b.first, b.second, ta);
        bytes.replace(a.first, a.second, tb);
      } else {
        if (bytes.size() < 8) return "nothing to swap in " + name;
        const std::size_t words = bytes.size() / 4, a = 4 * uniform(rng, words), b = 4 * uniform(rng, words);
        for (int k = 0; k < 4; ++k) std::swap(bytes[a + k], bytes[b + k]);
      }
      write_bytes(file, bytes);
      return "swapped two fields of " + name;
    }
    case 3: {  // an extreme value in place of a number
      static const char* kText[] = {"nan", "inf", "-inf", "1e308", "-1e308", "1e-308", "0", "-0", "1e13", "4294967296"};
      if (is_text(file)) {
        const auto t = tokens(bytes);
        if (t.empty()) return "no field in " + name;
        const auto [at, length] = t[uniform(rng, t.size())];
        const char* value = kText[uniform(rng, std::size(kText))];
        bytes.replace(at, length, value);
        write_bytes(file, bytes);
        return fmt::format("set a field of {} to {}", name, value);
      }
      static const float kFloat[] = {NAN, INFINITY, -INFINITY, 1e30f, -1e30f, 3e38f, 0.0f, -0.0f, 1e-40f};
      if (bytes.size() < 4) return "no value in " + name;
      const float value = kFloat[uniform(rng, std::size(kFloat))];
      std::memcpy(&bytes[4 * uniform(rng, bytes.size() / 4)], &value, 4);
      write_bytes(file, bytes);
      return fmt::format("set a 4-byte value of {} to {}", name, value);
    }
    default: {  // two files swapped
      const fs::path& other = files[uniform(rng, files.size())];
      const std::string other_bytes = read_bytes(other);
      write_bytes(other, bytes);
      write_bytes(file, other_bytes);
      return fmt::format("swapped {} and {}", name, other.filename().string());
    }
  }
}

class SequenceDamageProperty : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / fmt::format("slamvdb-SequenceDamageProperty-{}", ::getpid());
    fs::remove_all(root_);
    fs::create_directories(root_);
    synth::SynthConfig config;  // SIMULATED: a short drive with a small LiDAR and camera
    config.length_m = 3.0;
    config.lidar.beams = 16;
    config.lidar.columns = 256;
    config.image_width = 64;
    config.image_height = 40;
    synth::write_synthetic_sequence(config, pristine());
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }
  static fs::path pristine() { return root_ / "pristine"; }

  struct Case {
    std::string damages;
    testing::CommandResult result;
    std::string map_problem;  // "" when the map loads and is finite, or when none was written
  };

  static Case run_case(int seed) {
    Case c;
    const fs::path dir = root_ / fmt::format("case{}", seed), map = root_ / fmt::format("case{}.svdb", seed);
    fs::copy(pristine(), dir, fs::copy_options::recursive);
    std::vector<fs::path> files;
    for (const auto& entry : fs::recursive_directory_iterator(dir))
      if (entry.is_regular_file()) files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    Rng rng(static_cast<uint64_t>(seed));
    for (std::size_t n = 1 + uniform(rng, 3); n > 0; --n) c.damages += damage(files, rng) + "; ";
    c.result = testing::run_command(fmt::format("exec {} map {} -o {} --dim 8 --feature-size 16x10",
                                                testing::shell_quote(SLAMVDB_CLI_PATH),
                                                testing::shell_quote(dir.string()), testing::shell_quote(map.string())),
                                    60.0);
    if (c.result.exit_code == 0) {
      try {
        c.map_problem = testing::first_non_finite_value(load_map(map));
      } catch (const std::exception& e) {
        c.map_problem = std::string("the map written does not load: ") + e.what();
      }
    } else if (fs::exists(map)) {
      c.map_problem = "a failed run left a map file";
    }
    fs::remove_all(dir);
    fs::remove(map);
    return c;
  }

  static inline fs::path root_;  // TempDir needs a running test; this suite shares one sequence
};

TEST_F(SequenceDamageProperty, MapNeverCrashesHangsOrWritesNonFiniteValues) {
  const char* env = std::getenv("SLAMVDB_DAMAGE_CASES");
  const int cases = env ? std::max(1, std::atoi(env)) : 24;
  int exit_codes[3] = {0, 0, 0};
  // Two cases at a time: most of a case is the CLI starting up.
  for (int first = 0; first < cases; first += 2) {
    std::vector<std::future<Case>> running;
    for (int seed = first; seed < std::min(cases, first + 2); ++seed)
      running.push_back(std::async(std::launch::async, run_case, seed));
    for (std::size_t k = 0; k < running.size(); ++k) {
      const Case c = running[k].get();
      const std::string context = fmt::format("case {}: {}\n{}", first + static_cast<int>(k), c.damages, c.result.output);
      EXPECT_FALSE(c.result.timed_out) << "hang: " << context;
      EXPECT_EQ(c.result.signal, 0) << "killed by signal " << c.result.signal << ": " << context;
      EXPECT_TRUE(c.result.exited() && c.result.exit_code <= 2) << "exit code " << c.result.exit_code << ": " << context;
      EXPECT_EQ(c.map_problem, "") << context;
      if (c.result.exited() && c.result.exit_code <= 2) ++exit_codes[c.result.exit_code];
    }
  }
  // The damage must exercise both outcomes: maps that are still made, and refusals.
  std::printf("%d cases: %d mapped, %d refused (exit 1), %d usage errors (exit 2)\n", cases, exit_codes[0],
              exit_codes[1], exit_codes[2]);
  if (cases >= 24) {
    EXPECT_GT(exit_codes[0], 0);
    EXPECT_GT(exit_codes[1], 0);
  }
}

}  // namespace
}  // namespace slamvdb
