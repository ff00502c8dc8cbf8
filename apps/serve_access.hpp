#pragma once
// What `serve` and live mode (`map|slam --serve`) share: who may reach a server (loopback unless
// a bearer token or an explicit --insecure-no-auth), the token file, and ending a server on
// SIGINT / SIGTERM. One copy, so the two can never accept different things.
#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <string>
#include <utility>

#include "option_checks.hpp"
#include "slamvdb/core/error.hpp"

namespace slamvdb::cli {

inline bool is_loopback(const std::string& address) {
  return address == "localhost" || address == "::1" || address.rfind("127.", 0) == 0;
}

// Another address than loopback needs a token or an explicit no-auth: a map must not be readable
// by the whole network because of a typo. `option`: the option that gave the address.
inline void check_serve_access(const std::string& option, const std::string& bind, bool has_token,
                               bool insecure_no_auth, const std::string& token_option,
                               const std::string& no_auth_option) {
  if (!is_loopback(bind) && !has_token && !insecure_no_auth)
    usage_error(fmt::format("{} {}: another address than loopback needs {} FILE (or {})", option, bind, token_option,
                            no_auth_option));
}

// "[ADDR:]PORT" (ADDR may be [v6]): the address (loopback when not given) and the port 0..65535.
inline std::pair<std::string, int> parse_serve_address(const std::string& option, const std::string& text) {
  std::string bind = "127.0.0.1", port = text;
  if (const auto colon = text.rfind(':'); colon != std::string::npos) {
    bind = text.substr(0, colon);
    port = text.substr(colon + 1);
    if (bind.size() >= 2 && bind.front() == '[' && bind.back() == ']') bind = bind.substr(1, bind.size() - 2);
    if (bind.empty()) usage_error(fmt::format("{} {}: the address before ':' is empty", option, text));
  }
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) > 65535)
    usage_error(fmt::format("{} {}: expected [ADDR:]PORT with a port in 0..65535 (0: a free one)", option, text));
  return {bind, std::stoi(port)};
}

// The bearer token from its file: the first line, without surrounding blanks; at least 16
// characters (a short token is guessed).
inline std::string read_token(const std::string& option, const std::string& file) {
  std::ifstream in(file);
  std::string token;
  if (!in || !std::getline(in, token)) throw Error(fmt::format("{} {}: cannot read a line", option, file));
  const auto first = token.find_first_not_of(" \t\r");
  const auto last = token.find_last_not_of(" \t\r");
  token = first == std::string::npos ? "" : token.substr(first, last - first + 1);
  if (token.size() < 16)
    throw Error(fmt::format("{} {}: the token has {} characters; use at least 16", option, file, token.size()));
  return token;
}

// SIGINT / SIGTERM as a byte on a pipe: the handler only writes it (async-signal safe, whichever
// thread the signal lands on), a thread that waits reads it and stops the server outside any
// handler. One per process.
class StopSignal {
 public:
  StopSignal() {
    if (pipe(fds()) != 0) throw Error("cannot create the stop pipe");
    struct sigaction on_stop {};
    on_stop.sa_handler = [](int signal) { notify(static_cast<char>(signal)); };
    sigemptyset(&on_stop.sa_mask);
    sigaction(SIGINT, &on_stop, nullptr);
    sigaction(SIGTERM, &on_stop, nullptr);
  }
  // From a signal or a thread (0: the server ended by itself).
  static void notify(char byte = 0) { [[maybe_unused]] const auto n = write(fds()[1], &byte, 1); }
  // Blocks until notified; the signal's number (0: notify()).
  int wait() const {
    char signal = 0;
    while (read(fds()[0], &signal, 1) < 0 && errno == EINTR) {
    }
    return signal;
  }

 private:
  static int* fds() {
    static int pipe_fds[2] = {-1, -1};
    return pipe_fds;
  }
};

}  // namespace slamvdb::cli
