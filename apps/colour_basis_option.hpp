#pragma once
// `--colour-basis MAP.svdb`: draw (or record) PCA colours in the basis saved in another map of the
// same embedding space, so that the same thing has the same colour in both maps. `map`, `slam`
// and `demo` record a basis in every map they save (adopted with this option, else fitted on the
// new map); `export` draws in the map's own basis unless this option names another one.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <optional>
#include <string>

#include "option_checks.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/map_export.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli {

struct ColourBasisChoice {
  std::string file;                  // the map whose basis to use ('' = none given)
  std::string model_id;              // that map's embedding space
  std::optional<ColourBasis> basis;  // read by check_colour_basis_option
};

inline void add_colour_basis_option(CLI::App* cmd, ColourBasisChoice& choice) {
  cmd->add_option("--colour-basis", choice.file,
                  "Use the PCA colour basis saved in this map file (same embedding space), so both maps share "
                  "colours; default: the map's own")
      ->check(CLI::ExistingFile);
}

// Reads the basis before any long work; a map without one (saved before bases were recorded), or
// of another dimension, is an error naming the file.
inline void check_colour_basis_option(ColourBasisChoice& choice, int dim) {
  if (choice.file.empty()) return;
  const MapFileSummary summary = read_map_summary(choice.file);
  if (!summary.info.colour_basis)
    throw Error(fmt::format("--colour-basis {}: this map has no saved colour basis (it was made before bases were "
                            "recorded: make it again with this version's `slamvdb map`, or leave --colour-basis out)",
                            choice.file));
  if (summary.params.semantic.dim != dim)
    usage_error(fmt::format("--colour-basis {}: its embeddings are {}-d, this map's are {}-d", choice.file,
                            summary.params.semantic.dim, dim));
  choice.basis = summary.info.colour_basis;
  choice.model_id = summary.info.model_id;
}

// Records the colour basis in a map about to be saved: the adopted one when its embedding space is
// the map's (otherwise a warning, and a basis fitted on this map: nothing is lost), else a fitted one.
inline void record_colour_basis(SemanticMap& map, const ColourBasisChoice& choice) {
  if (map.num_index_cells() == 0) return;  // nothing to fit on, nothing to draw
  MapInfo info = map.info();
  if (choice.basis && choice.model_id == info.model_id) {
    info.colour_basis = choice.basis;
  } else {
    if (choice.basis)
      spdlog::warn("--colour-basis {} is in embedding space '{}' but this map is in '{}': fitted a basis of its own",
                   choice.file, escape_control(choice.model_id), escape_control(info.model_id));
    info.colour_basis = fit_pca_colouring(map);
  }
  map.set_info(std::move(info));
}

}  // namespace slamvdb::cli
