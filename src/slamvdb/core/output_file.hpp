#pragma once
// The one writer of every output (every command, every format, the map file too). What happens
// depends on what is at the path when the write starts:
//
//  - nothing, or a regular file: all-or-nothing replacement. The bytes go to a hidden temporary
//    sibling ".NAME.tmp-PID-N" (same directory, so the same file system), which is flushed,
//    fsynced and renamed over the target; the directory is fsynced last. A failed write (full disk,
//    read-only directory, an exception in the caller, the process killed) leaves the target as it
//    was: absent, or the previous complete file. A replaced file keeps its permission bits (and
//    owner and group where this process may set them); other hard links to it keep the old bytes.
//  - a symbolic link: followed (a chain too); the rule applies to what it points to, so the link
//    stays a link and its target is replaced atomically (a dangling link's target is created).
//  - a character device or a FIFO (/dev/null, a terminal, a named pipe), and /dev/stdout,
//    /dev/stderr, /dev/fd/N, /proc/self/fd/N (written to that already-open descriptor, so shell
//    redirections, appends and pipes behave as for any other program): written through, every
//    write and the final close checked; never replaced. Opening a FIFO waits for a reader.
//  - a directory, a block device or a socket: refused before anything is written.
//
// Every failure is an Error naming the file and the reason ("cannot write X: No space left on
// device"; a reader that went away is "Broken pipe", not a SIGPIPE that kills the process).
//
//   OutputFile out(path);               // or: write_output_file(path, bytes);
//   out.write(header); out.write(data);
//   out.commit();                       // without commit() nothing is replaced (see ~OutputFile)
//
// Writers that need a file name (SQLite, a library's save function) use temp_path(), or
// write_output_file_with(): for a file target that is the temporary sibling; for a device or FIFO
// it is a temporary file in the system's temporary directory ($TMPDIR, else /tmp) whose bytes are
// copied through (checked) at commit and which is removed then.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

namespace slamvdb {

struct OutputOptions {
  // fsync the file before the rename and the directory after it: the new content survives a power
  // loss. Without it the write is still all-or-nothing for readers and against a killed process;
  // writers of many files turn it off and call sync_file_system() once at the end.
  bool sync = true;
};

enum class OutputKind {
  kNewFile,      // nothing there yet: created atomically
  kRegularFile,  // replaced atomically
  kStream,       // a character device, a FIFO or an open descriptor: written through
};

// Where an output's bytes go, decided before any work (commands check their outputs with it).
struct OutputTarget {
  std::filesystem::path path;      // as given
  std::filesystem::path resolved;  // symbolic links followed: the file created, replaced or opened
  OutputKind kind = OutputKind::kNewFile;
  int descriptor = -1;             // /dev/stdout, /dev/fd/N ...: the descriptor written to
  std::string what;                // for messages: "a regular file", "a FIFO (named pipe)", "standard output" ...

  bool is_stream() const { return kind == OutputKind::kStream; }
};

// Follows symbolic links and classifies the path by the rule above. Throws Error naming the path
// and the reason for a path that is refused (a directory, a block device, a socket, a loop of
// symbolic links, a parent that is not a directory, an unreadable link, ...). Nothing is created.
OutputTarget resolve_output(const std::filesystem::path& path);

class OutputFile {
 public:
  // Resolves the target and creates the temporary file or opens the stream (a FIFO: waits for
  // its reader). Throws Error naming the target if that is impossible (missing or read-only
  // directory, a refused kind of file, ...).
  explicit OutputFile(std::filesystem::path target, OutputOptions options = {});
  // Not committed: removes the temporary file; a stream is closed (what was written through to a
  // device or FIFO cannot be taken back).
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // Appends bytes; throws Error naming the target on failure (e.g. "No space left on device").
  void write(const void* data, std::size_t bytes);
  void write(std::string_view bytes) { write(bytes.data(), bytes.size()); }
  // File: flushes, (fsyncs,) closes and renames the temporary over the target, (fsyncs the
  // directory). Stream: copies a named temporary through if temp_path() was used, then closes,
  // checked. Throws Error naming the target; the temporary is removed on failure.
  void commit();

  const std::filesystem::path& target() const { return target_; }
  const OutputTarget& destination() const { return destination_; }
  bool is_stream() const { return destination_.is_stream(); }
  // A file to write by name instead of write() (see the header comment); write() then appends to it.
  const std::filesystem::path& temp_path();

 private:
  void open_named_temp(const std::filesystem::path& dir, bool replaces_regular_file);
  void keep_permissions() noexcept;
  void copy_temp_through();
  void write_all(int fd, const char* data, std::size_t bytes);
  [[noreturn]] void fail(const std::string& reason);
  void discard() noexcept;

  std::filesystem::path target_, temp_;
  OutputTarget destination_;
  OutputOptions options_;
  int fd_ = -1;         // the temporary file
  int stream_fd_ = -1;  // the device, FIFO or descriptor written through
  bool committed_ = false;
  bool replaces_regular_file_ = false;
};

// The whole file in one call.
void write_output_file(const std::filesystem::path& target, std::string_view bytes, OutputOptions options = {});
// For writers that take a file name: `write(file)` writes the file named (any Error or exception
// it throws leaves the target untouched and the temporary removed), then it is committed.
void write_output_file_with(const std::filesystem::path& target,
                            const std::function<void(const std::filesystem::path& file)>& write,
                            OutputOptions options = {});

// True for the temporaries' names: ".NAME.tmp-PID-N".
bool is_output_temp_file(const std::filesystem::path& path);

// Removes the temporaries in `dir` that writers left behind when they were killed (their process
// no longer runs; checked by the PID in the name, so on the writing machine only), only those of
// the file named `of_file` if it is given. Returns how many. Temporaries of running processes,
// this one included, are kept.
std::size_t remove_stale_temp_files(const std::filesystem::path& dir, std::string_view of_file = {});

// fsync of a directory (makes renames and new entries in it durable); throws Error naming it.
void sync_directory(const std::filesystem::path& dir);
// syncfs(2) of the file system holding `path`: one flush after writing many files unsynced.
void sync_file_system(const std::filesystem::path& path);

}  // namespace slamvdb
