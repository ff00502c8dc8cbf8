#pragma once
// The files a command reads and writes, declared once beside its options and checked once after
// parsing, before any work, the same way for every command:
//  - every output, by the one writer's rule (core/output_file.hpp): a directory, block device or
//    socket, a missing or read-only directory, a device or FIFO it may not write: a usage error
//    (exit 2) naming the option. An output made of several files (a PNG and its map_server .yaml,
//    PREFIX.pgm/.yaml/.png, three .npy) cannot go to one device or FIFO: a usage error too.
//  - an output that is the same file as an input, by device and inode (so a hard link or a symbolic
//    link to the input counts, whatever its name), or the same file as another output: a usage
//    error, and the input is untouched. `--config FILE` counts as an input. Devices and FIFOs may
//    take several outputs (`-o /dev/null --json /dev/null`); they are never inputs (readers refuse them).
//  - outputs a command works on for long (a map file growing while mapping, a folder filled for
//    minutes) are locked for the run (core/output_lock.hpp): a second run given the same output fails
//    at once (exit 1) naming the run that holds it.
//
//   auto io = std::make_shared<IoOptions>(cmd);
//   io->input("map", opt->map);
//   io->output("-o", opt->csv);
//   io->output("--png", opt->png, png_with_yaml);
//   cmd->callback([opt, io] { io->check(); run(*opt); });
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "option_checks.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/core/output_lock.hpp"
#include "slamvdb/io/map_pictures.hpp"

namespace slamvdb::cli {

// Every file written for an option's value (default: the value itself).
using FilesOf = std::function<std::vector<std::filesystem::path>(const std::string& value)>;

// A picture and its map_server YAML (io/map_pictures.hpp: write_png_with_yaml).
inline std::vector<std::filesystem::path> png_with_yaml(const std::string& png) {
  return {png, map_server_yaml_path(png)};
}

class IoOptions {
  using Values = std::function<std::vector<std::string>()>;

 public:
  explicit IoOptions(const CLI::App* command = nullptr) : command_(command) {}

  // An option naming files (or a folder) the command reads: a std::string, std::filesystem::path or
  // std::vector<std::string> of the command's options, read at check().
  template <class Value>
  void input(std::string option, const Value& value) {
    inputs_.push_back({std::move(option), values_getter(value)});
  }
  // Files read that no single option names (e.g. the files of a folder), listed at check().
  void input_files(std::string option, std::function<std::vector<std::string>()> files) {
    inputs_.push_back({std::move(option), std::move(files)});
  }
  // An option naming a file the command writes; `files` lists every file written for its value.
  // lock: held for the run (commands that write the output while working for long).
  template <class Value>
  void output(std::string option, const Value& value, FilesOf files = {}, bool lock = false) {
    outputs_.push_back({std::move(option), values_getter(value), std::move(files), false, lock});
  }
  // A folder the command creates or fills; `files`: the files in it known up front (compared with
  // the inputs like any output).
  template <class Value>
  void output_folder(std::string option, const Value& value, FilesOf files = {}, bool lock = false) {
    outputs_.push_back({std::move(option), values_getter(value), std::move(files), true, lock});
  }

  // The checks above; usage errors are CLI::ValidationError (exit 2), a held lock an Error (exit 1).
  // Call first thing in the command's callback. Locks stay held until this object goes.
  void check();

 private:
  struct Input {
    std::string option;
    Values values;
  };
  struct Output {
    std::string option;
    Values values;
    FilesOf files;
    bool folder = false, lock = false;
  };
  // A file's identity: device and inode when it exists, else its absolute path.
  struct Identity {
    dev_t device = 0;
    ino_t inode = 0;
    std::string path;
    bool operator==(const Identity&) const = default;
  };
  struct Named {
    std::string option, value;
    Identity id;
  };

  static Values values_getter(const std::string& value) {
    return [&value] { return value.empty() ? std::vector<std::string>{} : std::vector<std::string>{value}; };
  }
  static Values values_getter(const std::filesystem::path& value) {
    return [&value] { return value.empty() ? std::vector<std::string>{} : std::vector<std::string>{value.string()}; };
  }
  static Values values_getter(const std::vector<std::string>& values) {
    return [&values] {
      std::vector<std::string> out;
      for (const std::string& v : values)
        if (!v.empty()) out.push_back(v);
      return out;
    };
  }

  static std::optional<Identity> existing_identity(const std::filesystem::path& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
    return Identity{st.st_dev, st.st_ino, {}};
  }

  std::vector<Named> input_files() const;
  void check_folder(const Output& out, const std::string& value) const;
  // The output's identity (nullopt for a device or FIFO); usage error if the path is refused.
  std::optional<Identity> check_output_file(const std::string& option, const std::filesystem::path& file,
                                            std::size_t files_of_value, bool in_new_folder) const;

  const CLI::App* command_;
  std::vector<Input> inputs_;
  std::vector<Output> outputs_;
  std::vector<std::unique_ptr<OutputLock>> locks_;
};

inline std::vector<IoOptions::Named> IoOptions::input_files() const {
  std::vector<Named> files;
  std::vector<Input> all = inputs_;
  // `--config FILE` (an option of the top-level app) is read too.
  std::vector<std::string> config;
  if (command_ && command_->get_parent())
    if (const CLI::Option* o = command_->get_parent()->get_option_no_throw("--config"); o && o->count() > 0)
      config = o->results();
  all.push_back({"--config", values_getter(config)});
  for (const Input& in : all)
    for (const std::string& value : in.values())
      if (const auto id = existing_identity(value)) files.push_back({in.option, value, *id});
  return files;
}

inline void IoOptions::check_folder(const Output& out, const std::string& value) const {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(value, ec);  // symbolic links followed
  if (std::filesystem::exists(status) && !std::filesystem::is_directory(status))
    usage_error(fmt::format("{} {}: it exists and is not a folder; give a folder (missing or to fill)", out.option, value));
}

inline std::optional<IoOptions::Identity> IoOptions::check_output_file(const std::string& option,
                                                                       const std::filesystem::path& file,
                                                                       std::size_t files_of_value,
                                                                       bool in_new_folder) const {
  namespace fs = std::filesystem;
  OutputTarget target;
  try {
    target = resolve_output(file);
  } catch (const Error& e) {
    usage_error(fmt::format("{}: {}", option, e.what()));
  }
  if (target.is_stream()) {
    if (files_of_value > 1)
      usage_error(fmt::format("{} {}: it is {}, and this output is {} files; a device or FIFO takes one: give a file name",
                              option, file.string(), target.what, files_of_value));
    if (target.descriptor < 0 && ::access(target.resolved.c_str(), W_OK) != 0)
      usage_error(fmt::format("{} {}: {} that this process may not write", option, file.string(), target.what));
    return std::nullopt;
  }
  const fs::path dir = target.resolved.parent_path().empty() ? fs::path(".") : target.resolved.parent_path();
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    if (in_new_folder) return Identity{0, 0, fs::weakly_canonical(fs::absolute(target.resolved), ec).string()};
    usage_error(fmt::format("{} {}: directory {} does not exist", option, file.string(), dir.string()));
  }
  if (::access(dir.c_str(), W_OK) != 0)
    usage_error(fmt::format("{} {}: cannot write into directory {}: {}", option, file.string(), dir.string(),
                            std::strerror(errno)));
  if (const auto id = existing_identity(target.resolved)) return id;
  return Identity{0, 0, fs::weakly_canonical(fs::absolute(target.resolved), ec).string()};
}

inline void IoOptions::check() {
  const std::vector<Named> inputs = input_files();
  std::vector<Named> written;
  std::vector<std::filesystem::path> to_lock;
  for (const Output& out : outputs_) {
    for (const std::string& value : out.values()) {
      bool new_folder = false;
      if (out.folder) {
        check_folder(out, value);
        new_folder = !std::filesystem::exists(value);
      }
      std::vector<std::filesystem::path> files;
      if (out.files) files = out.files(value);
      else if (!out.folder) files = {value};
      for (const std::filesystem::path& file : files) {
        const auto id = check_output_file(out.option, file, files.size(), new_folder);
        if (!id) continue;  // a device or FIFO
        for (const Named& in : inputs)
          if (id->path.empty() && in.id == *id)
            usage_error(fmt::format("{} {} is the same file as {} {}: writing it would destroy the input; choose "
                                    "another output",
                                    out.option, file.string(), in.option, in.value));
        for (const Named& other : written)
          if (other.id == *id)
            usage_error(fmt::format("{} {} and {} {} are the same file: give each output its own", other.option,
                                    other.value, out.option, file.string()));
        written.push_back({out.option, file.string(), *id});
      }
      if (out.lock && (out.folder || !resolve_output(value).is_stream())) to_lock.push_back(value);
    }
  }
  for (const std::filesystem::path& output : to_lock) locks_.push_back(std::make_unique<OutputLock>(output));
}

}  // namespace slamvdb::cli
