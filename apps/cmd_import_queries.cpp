// `slamvdb import-queries`: a folder of per-class CSV query vectors (the authors' prototype layout)
// -> one query set file.
#include <fmt/format.h>

#include "command_registry.hpp"
#include "feature_options.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "io_options.hpp"
#include "slamvdb/ontology/ontology.hpp"
#include "slamvdb/query/query_set.hpp"

namespace slamvdb::cli::cmd_import_queries {
namespace {

struct Options {
  std::string dir, output, model_id, ontology;
};

void run(const Options& opt) {
  std::optional<Ontology> ontology;
  if (!opt.ontology.empty()) ontology = Ontology::load_or_builtin(opt.ontology);
  const QuerySet q = import_query_csv_dir(opt.dir, opt.model_id, ontology ? &*ontology : nullptr);
  save_query_set(opt.output, q);
  // Names and ids come from files: printed with control characters escaped.
  std::vector<std::string> names;
  for (const std::string& name : q.names) names.push_back(escape_control(name));
  fmt::print("{} classes ({}), {}-d, model {}{} -> {}\n", q.size(), fmt::join(names, ", "), q.dim(),
             escape_control(q.model_id),
             ontology ? ", order and colours from ontology " + escape_control(ontology->name()) : std::string(),
             opt.output);
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "import-queries",
      "Import a folder of query vectors, one CLASS.csv per class holding one line of comma-separated floats (the "
      "authors' prototype layout), into a query set file");
  cmd->add_option("csv_dir", opt->dir, "Folder of CLASS.csv files")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", opt->output, "Query set file to write (.json)")->required();
  cmd->add_option("--model-id", opt->model_id,
                  "Model id of the embedding space the vectors belong to (the map's model id, see `slamvdb info`)")
      ->required();
  cmd->add_option("--ontology", opt->ontology,
                  "Ontology (file or built-in name) giving class order, colours and void classes; every class needs "
                  "a file");
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("--ontology", opt->ontology);
  io->input_files("csv_dir", [opt] {  // the CLASS.csv files read
    std::vector<std::string> files;
    std::error_code ec;
    for (std::filesystem::directory_iterator it(opt->dir, ec), end; !ec && it != end; it.increment(ec))
      if (it->path().extension() == ".csv") files.push_back(it->path().string());
    return files;
  });
  io->output("-o", opt->output);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_import_queries
