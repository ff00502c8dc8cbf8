#pragma once
// `--config FILE.yaml` for every command: the options of a command as a YAML mapping, keys being
// the long option names (`voxel-size: 0.2`, underscores accepted for dashes), lists as YAML
// sequences, flags as booleans; positional arguments stay on the command line. Options on the command line
// win over the file. Unknown keys are errors (a typo must not be ignored silently).
// CLI11 reads TOML/INI only; this is its Config interface over yaml-cpp.
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <sstream>
#include <string>
#include <vector>

namespace slamvdb::cli {

class YamlConfig : public CLI::Config {
 public:
  // CLI11 reads config files at the top level only: keys outside a section belong to this
  // subcommand (the one on the command line), so a file for `map` holds `map`'s options directly.
  explicit YamlConfig(std::string section = {}) : section_(std::move(section)) {}

  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override {
    YAML::Node root;
    try {
      root = YAML::Load(input);
    } catch (const YAML::Exception& e) {
      throw CLI::ConfigError(std::string("config file: ") + e.what());
    }
    std::vector<CLI::ConfigItem> items;
    if (root.IsNull()) return items;
    if (!root.IsMap()) throw CLI::ConfigError("config file: expected a mapping of option names to values");
    collect(root, section_.empty() ? std::vector<std::string>{} : std::vector<std::string>{section_}, items);
    return items;
  }

  // The options as YAML (used for --help of --config and for the effective configuration a map
  // records): given values, and defaults too with default_also.
  std::string to_config(const CLI::App* app, bool default_also, bool, std::string) const override {
    YAML::Emitter out;
    out << YAML::BeginMap;
    for (const CLI::Option* opt : app->get_options()) {
      const std::string name = key_of(*opt);
      if (name.empty() || name == "help" || name == "help-all" || name == "config" || name == "version") continue;
      std::vector<std::string> values;
      if (opt->count() > 0) {
        values = opt->results();
      } else if (default_also && !opt->get_default_str().empty()) {
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

 private:
  std::string section_;

  static std::string key_of(const CLI::Option& opt) {
    return opt.get_lnames().empty() ? std::string() : opt.get_lnames().front();
  }

  static void collect(const YAML::Node& map, const std::vector<std::string>& parents,
                      std::vector<CLI::ConfigItem>& items) {
    for (const auto& entry : map) {
      std::string name = entry.first.as<std::string>();
      for (char& c : name)
        if (c == '_') c = '-';
      const YAML::Node& value = entry.second;
      CLI::ConfigItem item;
      item.parents = parents;
      item.name = name;
      if (value.IsMap()) {  // a section: the options of a subcommand
        std::vector<std::string> inner = parents;
        inner.push_back(name);
        collect(value, inner, items);
        continue;
      }
      if (value.IsSequence()) {
        for (const auto& v : value) {
          if (!v.IsScalar()) throw CLI::ConfigError("config file: '" + name + "' must be a list of plain values");
          item.inputs.push_back(v.as<std::string>());
        }
      } else if (value.IsScalar()) {
        item.inputs.push_back(value.as<std::string>());
      } else {
        throw CLI::ConfigError("config file: '" + name + "' has no value");
      }
      items.push_back(std::move(item));
    }
  }
};

// Gives the top-level app a --config option reading YAML for `subcommand`; unknown keys in the
// file are errors.
inline void add_yaml_config(CLI::App& app, const std::string& subcommand) {
  app.config_formatter(std::make_shared<YamlConfig>(subcommand));
  app.set_config("--config", "",
                 "Read the command's options from this YAML file (long option names as keys, e.g. `voxel-size: 0.2`; "
                 "the command line wins)");
  app.allow_config_extras(CLI::config_extras_mode::error);
}

// The command's effective options as YAML: what it ran with, defaults included.
inline std::string effective_config(const CLI::App& cmd) { return YamlConfig().to_config(&cmd, true, false, ""); }

}  // namespace slamvdb::cli
