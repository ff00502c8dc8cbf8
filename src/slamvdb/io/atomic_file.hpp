#pragma once
// All-or-nothing file writes. The bytes go to a hidden temporary sibling of the target
// (".NAME.tmp-PID-N", same directory, so the same file system), which is flushed, fsynced and then
// renamed over the target; the directory is fsynced last. A write that fails (full disk, read-only
// or missing directory, an exception in the caller, the process killed) leaves the target as it
// was: absent, or the previous complete file. Nothing that looks complete is ever half written.
//
//   AtomicFile out(path);               // or: write_file_atomically(path, bytes);
//   out.write(header); out.write(data);
//   out.commit();                       // without commit() the destructor removes the temporary
//
// Writers that need a file name (SQLite, a library's save function) write to temp_path() and
// commit, or use write_file_atomically_with(). A target that is a symbolic link is replaced by
// the new file, not written through.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string_view>

namespace slamvdb {

struct AtomicWriteOptions {
  // fsync the file before the rename and the directory after it: the new content survives a power
  // loss. Without it the write is still all-or-nothing for readers and against a killed process;
  // writers of many files turn it off and call sync_file_system() once at the end.
  bool sync = true;
};

class AtomicFile {
 public:
  // Creates the temporary file; throws Error naming the target if that is impossible (missing or
  // read-only directory, ...).
  explicit AtomicFile(std::filesystem::path target, AtomicWriteOptions options = {});
  ~AtomicFile();  // not committed: closes and removes the temporary file
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  // Appends bytes; throws Error naming the target on failure (e.g. "No space left on device").
  void write(const void* data, std::size_t bytes);
  void write(std::string_view bytes) { write(bytes.data(), bytes.size()); }
  // Flushes, (fsyncs,) closes and renames the temporary over the target, (fsyncs the directory).
  // Throws Error naming the target; the temporary is removed on failure.
  void commit();

  const std::filesystem::path& target() const { return target_; }
  // The temporary file, for writers that need a name. It is open for writing; write() appends to it.
  const std::filesystem::path& temp_path() const { return temp_; }

 private:
  void discard() noexcept;

  std::filesystem::path target_, temp_;
  AtomicWriteOptions options_;
  int fd_ = -1;
  bool committed_ = false;
};

// The whole file in one call.
void write_file_atomically(const std::filesystem::path& target, std::string_view bytes,
                           AtomicWriteOptions options = {});
// For writers that take a file name: `write(temp)` writes the temporary (any Error or exception it
// throws leaves the target untouched and the temporary removed), then it is committed.
void write_file_atomically_with(const std::filesystem::path& target,
                                const std::function<void(const std::filesystem::path& temp)>& write,
                                AtomicWriteOptions options = {});

// True for the temporaries' names: ".NAME.tmp-PID-N".
bool is_atomic_temp_file(const std::filesystem::path& path);

// Removes the temporaries in `dir` that writers left behind when they were killed (their process
// no longer runs; checked by the PID in the name, so on the writing machine only). Returns how many.
// Temporaries of running processes, this one included, are kept.
std::size_t remove_stale_temp_files(const std::filesystem::path& dir);

// fsync of a directory (makes renames and new entries in it durable); throws Error naming it.
void sync_directory(const std::filesystem::path& dir);
// syncfs(2) of the file system holding `path`: one flush after writing many files unsynced.
void sync_file_system(const std::filesystem::path& path);

}  // namespace slamvdb
