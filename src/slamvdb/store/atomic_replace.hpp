#pragma once
// Replacing a file so that a crash or kill -9 at any moment leaves either the old file or the new
// one, never a mix: write a hidden temp sibling, fsync it, rename it over the target, fsync the
// directory.
#include <filesystem>
#include <functional>

namespace slamvdb::store {

// write(temp) fills the temp file; then it replaces `target`. Throws Error naming the files on
// failure (the target is then untouched and the temp file removed).
void replace_atomically(const std::filesystem::path& target,
                        const std::function<void(const std::filesystem::path& temp)>& write);

// Removes the temp files that killed writers of `target` left behind (their process is gone).
// Best effort: never throws.
void remove_stale_temp_files(const std::filesystem::path& target);

// fsync of a file or directory; throws Error naming it.
void fsync_path(const std::filesystem::path& p, bool directory);

}  // namespace slamvdb::store
