#pragma once
// `--config FILE.yaml` for every command: the options of a command as one YAML mapping, keys being
// the long option names (`voxel-size: 0.2`, underscores accepted for dashes), lists as YAML
// sequences, flags as `true` / `false`; positional arguments stay on the command line. Options on
// the command line win over the file. Unknown keys, an option set twice, a second YAML document,
// a complex key, a nested mapping, a key without a value and files over 1 MiB are usage errors
// naming the file (and the line).
//
// A value from the file goes through exactly the path of a command-line value: it is added as
// the option's raw text and converted, validated and checked with the command line's values (see
// command_line.hpp for when). CLI11's own config reader is not used: it opens the file with an
// ifstream (a FIFO blocks), and gives flags from a file no callback (they were recorded but did
// nothing).
#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"

namespace slamvdb::cli {

// A config file is a handful of options: anything larger is not one (and is not read whole).
inline constexpr std::uint64_t kMaxConfigBytes = std::uint64_t{1} << 20;

// One `key: value` of a config file.
struct ConfigEntry {
  std::string raw_key;              // as written
  std::string key;                  // dashes for underscores
  std::vector<std::string> values;  // the scalar, or the list's scalars
  bool is_list = false;
  int line = 0;  // 1-based
};

// Thrown for every problem with a config file: a usage error (exit code 2) whose message names
// the file.
inline CLI::ConfigError config_error(const std::string& file, int line, const std::string& what) {
  return CLI::ConfigError(line > 0 ? fmt::format("config file {}: line {}: {}", file, line, what)
                                   : fmt::format("config file {}: {}", file, what));
}

// The entries of a YAML config text, in file order (`file` names it in errors).
inline std::vector<ConfigEntry> parse_config_text(const std::string& text, const std::string& file) {
  std::vector<YAML::Node> documents;
  try {
    documents = YAML::LoadAll(text);
  } catch (const YAML::Exception& e) {
    throw config_error(file, e.mark.is_null() ? 0 : e.mark.line + 1, e.msg);
  }
  if (documents.size() > 1)
    throw config_error(file, documents[1].Mark().is_null() ? 0 : documents[1].Mark().line + 1,
                       fmt::format("{} YAML documents; a config file holds one mapping of options", documents.size()));
  std::vector<ConfigEntry> entries;
  if (documents.empty() || documents.front().IsNull()) return entries;
  const YAML::Node& root = documents.front();
  const auto line_of = [](const YAML::Node& n) { return n.Mark().is_null() ? 0 : n.Mark().line + 1; };
  if (!root.IsMap()) throw config_error(file, line_of(root), "expected a mapping of option names to values");
  std::map<std::string, int> seen;  // key -> line
  for (const auto& item : root) {
    const YAML::Node& key = item.first;
    const YAML::Node& value = item.second;
    ConfigEntry entry;
    entry.line = line_of(key);
    if (!key.IsScalar())
      throw config_error(file, entry.line, "a key must be an option name, not a YAML complex key (a list or mapping)");
    entry.raw_key = entry.key = key.Scalar();
    for (char& c : entry.key)
      if (c == '_') c = '-';
    if (const auto [it, inserted] = seen.emplace(entry.key, entry.line); !inserted)
      throw config_error(file, entry.line, fmt::format("'{}' is given twice (first on line {})", entry.raw_key, it->second));
    if (value.IsScalar()) {
      entry.values.push_back(value.Scalar());
    } else if (value.IsSequence()) {
      entry.is_list = true;
      for (const auto& v : value) {
        if (!v.IsScalar())
          throw config_error(file, line_of(v), fmt::format("'{}' must be a list of plain values", entry.key));
        entry.values.push_back(v.Scalar());
      }
      if (entry.values.empty()) throw config_error(file, entry.line, fmt::format("'{}' is an empty list", entry.key));
    } else if (value.IsMap()) {
      throw config_error(file, entry.line,
                         fmt::format("'{}' is a mapping; an option takes a value or a list of values", entry.key));
    } else {
      throw config_error(file, entry.line, fmt::format("'{}' has no value", entry.key));
    }
    entries.push_back(std::move(entry));
  }
  return entries;
}

// The entries of a config file, read like every other input (regular files only, opened without
// blocking, at most kMaxConfigBytes).
inline std::vector<ConfigEntry> read_config_file(const std::string& file) {
  std::string text;
  try {
    text = read_regular_file(file, "config file", kMaxConfigBytes);
  } catch (const Error& e) {
    throw CLI::ConfigError(e.what());
  }
  return parse_config_text(text, file);
}

// The option a config key names: its long name, a one-letter short name, or nullptr.
inline CLI::Option* option_of_key(CLI::App& cmd, const std::string& key) {
  if (key.empty() || key.front() == '-') return nullptr;
  if (CLI::Option* o = cmd.get_option_no_throw("--" + key)) return o;
  if (key.size() == 1) return cmd.get_option_no_throw("-" + key);
  return nullptr;
}

// Adds the file's values to the options of `cmd` that the command line left empty, as raw text
// (as if typed), so that they are converted, validated and checked with the command line's. Must
// run before any option callback of `cmd` (CommandLine makes sure of that).
inline void apply_config_file(CLI::App& cmd, const std::string& file) {
  const std::vector<ConfigEntry> entries = read_config_file(file);
  for (const CLI::Option* o : cmd.get_options())
    if (o->get_callback_run())  // a command that checks its options in its own parse_complete_callback
      throw std::logic_error(fmt::format("`{}` converted its options before --config was read: register its checks "
                                         "with add_option_checks, not parse_complete_callback",
                                         cmd.get_name()));
  std::map<const CLI::Option*, const ConfigEntry*> given;
  for (const ConfigEntry& e : entries) {
    CLI::Option* o = option_of_key(cmd, e.key);
    if (o == nullptr) {
      std::string underscores = e.key;  // positional names are written with underscores (out_dir)
      for (char& c : underscores)
        if (c == '-') c = '_';
      if (cmd.get_option_no_throw(e.key) != nullptr || cmd.get_option_no_throw(underscores) != nullptr)
        throw config_error(file, e.line,
                           fmt::format("'{}' is a positional argument of `{}`: give it on the command line", e.raw_key,
                                       cmd.get_name()));
      throw config_error(file, e.line, fmt::format("'{}' is not an option of `{}`", e.raw_key, cmd.get_name()));
    }
    if (!o->get_configurable())
      throw config_error(file, e.line, fmt::format("'{}' cannot be given in a config file", e.raw_key));
    if (const auto [it, inserted] = given.emplace(o, &e); !inserted)
      throw config_error(file, e.line,
                         fmt::format("'{}' sets {} again (first as '{}' on line {})", e.raw_key, o->get_name(),
                                     it->second->raw_key, it->second->line));
    if (!o->empty()) continue;  // the command line wins
    if (o->get_items_expected_max() == 0) {  // a flag: the text of `--flag=true` / `--flag=false`
      const std::string& v = e.values.front();
      const bool is_true = v == "true" || v == "True" || v == "TRUE";
      const bool is_false = v == "false" || v == "False" || v == "FALSE";
      if (e.is_list || !(is_true || is_false))
        throw config_error(file, e.line,
                           fmt::format("'{}' is a flag: its value is true or false, not '{}'", e.raw_key,
                                       e.is_list ? "a list" : v));
      const std::string name = o->get_lnames().empty() ? e.key : o->get_lnames().front();  // as CLI11 names it
      o->add_result(o->get_flag_value(name, is_true ? "true" : "false"));
    } else {
      o->add_result(e.values);
    }
  }
}

// The options of `cmd` as a config file (used for the effective configuration a map records):
// the values given (on the command line or in --config) and the defaults of the others.
inline std::string effective_config(const CLI::App& cmd) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  for (const CLI::Option* opt : cmd.get_options()) {
    if (opt->get_lnames().empty() || !opt->get_configurable()) continue;  // positionals, --help
    const std::string& name = opt->get_lnames().front();
    std::vector<std::string> values;
    if (opt->count() > 0) {
      values = opt->results();
    } else if (!opt->get_default_str().empty()) {
      values = {opt->get_default_str()};
    } else {
      continue;
    }
    out << YAML::Key << name << YAML::Value;
    if (values.size() == 1 && opt->get_expected_max() <= 1) {
      out << values.front();
    } else {
      out << YAML::Flow << values;
    }
  }
  out << YAML::EndMap;
  return out.c_str();
}

}  // namespace slamvdb::cli
