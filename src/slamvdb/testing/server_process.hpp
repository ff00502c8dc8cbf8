#pragma once
// For tests only: `slamvdb serve ... --port 0` as a child process, its chosen port read from the
// line it prints "serving MAP on http[s]://HOST:PORT/ ...", stopped by a signal at the end.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace slamvdb::testing {

class ServerProcess {
 public:
  // Starts `program args...` (stderr to `log`) and waits up to `timeout_seconds` for the line with
  // its address.
  ServerProcess(const std::string& program, const std::vector<std::string>& args, const std::string& log,
                double timeout_seconds = 60) {
    int fds[2];
    if (pipe(fds) != 0) throw std::runtime_error("pipe");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    std::vector<char*> argv{const_cast<char*>(program.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, program.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    out_ = fds[0];
    if (rc != 0) throw std::runtime_error("posix_spawn " + program);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_seconds);
    // Log lines may come first (spdlog writes to stdout): read until the address line is complete.
    const auto address_line_read = [&] {
      const auto at = output_.find("://");
      return at != std::string::npos && output_.find('\n', at) != std::string::npos;
    };
    while (!address_line_read() && std::chrono::steady_clock::now() < deadline) {
      pollfd p{out_, POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) continue;
      char c[256];
      const ssize_t n = read(out_, c, sizeof c);
      if (n <= 0) break;
      output_.append(c, static_cast<std::size_t>(n));
    }
    // http[s]://HOST:PORT/ (HOST may be [v6]): the port follows the authority's last ':'.
    const auto at = output_.find("://");
    const auto slash = at == std::string::npos ? at : output_.find('/', at + 3);
    const auto colon = slash == std::string::npos ? slash : output_.rfind(':', slash);
    if (colon != std::string::npos && colon > at + 3) port_ = std::atoi(output_.c_str() + colon + 1);
  }
  ~ServerProcess() {
    if (pid_ > 0) stop(SIGKILL);
    if (out_ >= 0) close(out_);
  }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  int port() const { return port_; }  // 0: the server printed no address (see output and the log)
  const std::string& output() const { return output_; }  // stdout up to the address line
  pid_t pid() const { return pid_; }

  // Waits up to `timeout_seconds` for the process to end by itself (e.g. `map --serve` when
  // mapping is done): its exit code (>= 0) or -signal; nothing while it still runs.
  std::optional<int> wait(double timeout_seconds) {
    if (pid_ <= 0) return exit_;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_seconds);
    for (;;) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        exit_ = WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
        return exit_;
      }
      if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  bool running() { return !wait(0.0); }
  // All of stdout: call once the process has ended (reads to the end).
  const std::string& read_all() {
    char c[4096];
    for (ssize_t n; out_ >= 0 && (n = read(out_, c, sizeof c)) > 0;) output_.append(c, static_cast<std::size_t>(n));
    return output_;
  }

  // Sends `signal` and waits: the exit code (>= 0), or -signal when a signal ended it.
  int stop(int signal = SIGTERM) {
    if (pid_ <= 0) return -1;
    kill(pid_, signal);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  int port_ = 0;
  std::string output_;
  std::optional<int> exit_;  // once wait() saw it end
};

}  // namespace slamvdb::testing
