#pragma once
// One run at a time per output. A command that works for long on an output (`map` and `slam`
// grow their map file while mapping) holds this lock from before its work starts until the output
// is complete, so a second run given the same output fails at once, naming the file and the run
// that holds it, instead of both writing it and one failing late ("attempt to write a readonly
// database") while the other's file silently loses the race.
//
// The lock is flock(2) on a hidden lock file beside the output, ".NAME.lock" (symbolic links
// followed, so two names of one file share it), holding the holder's PID and command line for the
// message. The kernel releases a flock when its process ends, however it ends (kill -9 too), so a
// dead run never blocks a later one; a lock file left by a killed run is taken over and removed
// by the next holder.
#include <filesystem>
#include <string>

namespace slamvdb {

class OutputLock {
 public:
  // Throws Error naming `output` and the holder ("... is being written by another slamvdb run:
  // PID 123, slamvdb map ...") when another process holds it, or naming the lock file and the
  // reason when it cannot be created.
  explicit OutputLock(const std::filesystem::path& output);
  ~OutputLock();  // removes the lock file and releases the lock
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

  const std::filesystem::path& lock_file() const { return lock_file_; }

 private:
  std::filesystem::path lock_file_;
  int fd_ = -1;
};

// The lock file of an output (a file or a folder): ".NAME.lock" beside what it names after
// symbolic links.
std::filesystem::path output_lock_file(const std::filesystem::path& output);

}  // namespace slamvdb
