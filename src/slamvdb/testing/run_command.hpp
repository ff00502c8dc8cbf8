#pragma once
// For tests only: runs a shell command (e.g. the CLI) with a time limit and reports how it ended:
// its exit code, or the signal that killed it, or that it was killed for running too long.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <thread>

extern char** environ;

namespace slamvdb::testing {

struct CommandResult {
  int exit_code = -1;      // when it exited
  int signal = 0;          // when a signal ended it (not ours)
  bool timed_out = false;  // killed by us after the time limit
  std::string output;      // stdout and stderr
  bool exited() const { return !timed_out && signal == 0 && exit_code >= 0; }
};

// `/bin/sh -c command`; start the command with `exec` so that a signal that kills the program is
// seen here, not hidden by the shell.
inline CommandResult run_command(const std::string& command, double timeout_seconds = 120.0) {
  static std::atomic<int> counter{0};
  const std::filesystem::path log = std::filesystem::temp_directory_path() /
                                    ("slamvdb_run_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  const char* argv[] = {"/bin/sh", "-c", command.c_str(), nullptr};
  pid_t pid = 0;
  CommandResult result;
  const int spawned = posix_spawn(&pid, "/bin/sh", &actions, nullptr, const_cast<char**>(argv), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    result.output = "posix_spawn failed";
    return result;
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_seconds);
  int status = 0;
  while (true) {
    const pid_t done = ::waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      result.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (!result.timed_out) {
    if (WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
    if (WIFSIGNALED(status)) result.signal = WTERMSIG(status);
  }
  std::ifstream in(log);
  result.output.assign(std::istreambuf_iterator<char>(in), {});
  std::filesystem::remove(log);
  return result;
}

// A shell word for `text` (single quotes).
inline std::string shell_quote(const std::string& text) {
  std::string out = "'";
  for (char c : text) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}
inline std::string quote_path(const std::filesystem::path& path) { return shell_quote(path.string()); }

// A command running in the background (`/bin/sh -c "exec ..."`, output to `log`), for tests that
// watch it work and kill it at a chosen moment.
class ChildProcess {
 public:
  ChildProcess(const std::string& command, const std::filesystem::path& log) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    const std::string exec_command = "exec " + command;
    const char* argv[] = {"/bin/sh", "-c", exec_command.c_str(), nullptr};
    if (posix_spawn(&pid_, "/bin/sh", &actions, nullptr, const_cast<char**>(argv), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess() {
    if (pid_ > 0 && !status_) kill_now();
  }
  bool started() const { return pid_ > 0; }
  // False once it has ended (its status is then kept).
  bool running() {
    if (pid_ <= 0 || status_) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) status_ = status;
    return !status_;
  }
  // SIGKILL, then waits; true when the signal ended it (false: it had already ended by itself).
  bool kill_now() {
    if (!running()) return false;
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    status_ = status;
    return WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
  }
  int wait_exit_code() {
    if (running()) {
      int status = 0;
      ::waitpid(pid_, &status, 0);
      status_ = status;
    }
    return status_ && WIFEXITED(*status_) ? WEXITSTATUS(*status_) : -1;
  }

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
};

#ifdef SLAMVDB_CLI_PATH
// The project's CLI with `args` (shell words, already quoted), as run_command runs it.
inline CommandResult run_cli(const std::string& args, double timeout_seconds = 120.0) {
  return run_command("exec " + shell_quote(SLAMVDB_CLI_PATH) + " " + args, timeout_seconds);
}
#endif

}  // namespace slamvdb::testing
