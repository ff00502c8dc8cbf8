#pragma once
// A one-line progress bar on stderr for long runs, with the rate in the given unit (scans/s,
// images/s) and an ETA; silent when stderr is not a terminal except for a final summary line, so
// logs and CI output stay readable; off entirely with `slamvdb --quiet`.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace slamvdb::cli {

class ProgressBar {
 public:
  ProgressBar(std::string label, std::size_t total, std::string unit = {})
      : label_(std::move(label)), unit_(std::move(unit)), total_(total), tty_(isatty(fileno(stderr))),
        start_(std::chrono::steady_clock::now()) {}
  static void set_enabled(bool on) { enabled() = on; }
  ~ProgressBar() { finish(); }

  void update(std::size_t done, const std::string& suffix = {}) {
    done_ = done;
    if (!tty_ || !enabled()) return;
    const auto now = std::chrono::steady_clock::now();
    if (done < total_ && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    draw(suffix);
  }
  void finish(const std::string& suffix = {}) {
    if (finished_) return;
    finished_ = true;
    if (!enabled()) return;
    if (tty_) {
      draw(suffix);
      std::fputc('\n', stderr);
    } else {
      std::fprintf(stderr, "%s: %zu/%zu in %.1f s%s %s\n", label_.c_str(), done_, total_, elapsed(), rate().c_str(),
                   suffix.c_str());
    }
  }

 private:
  static bool& enabled() {
    static bool on = true;
    return on;
  }
  std::string rate() const {
    if (unit_.empty()) return {};
    const double t = elapsed();
    char text[64];
    std::snprintf(text, sizeof text, ", %.1f %s/s", t > 0 ? done_ / t : 0.0, unit_.c_str());
    return text;
  }
  double elapsed() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  void draw(const std::string& suffix) {
    constexpr int kWidth = 30;
    const double frac = total_ ? static_cast<double>(done_) / total_ : 1.0;
    const int filled = static_cast<int>(frac * kWidth);
    std::string bar(filled, '#');
    bar.resize(kWidth, '-');
    const double t = elapsed();
    const double eta = frac > 0 ? t / frac - t : 0.0;
    std::fprintf(stderr, "\r%s [%s] %zu/%zu %.0f%% %.1fs%s eta %.1fs %s\033[K", label_.c_str(), bar.c_str(), done_,
                 total_, frac * 100.0, t, rate().c_str(), eta, suffix.c_str());
    std::fflush(stderr);
  }

  std::string label_, unit_;
  std::size_t total_, done_ = 0;
  bool tty_, finished_ = false;
  std::chrono::steady_clock::time_point start_, last_{};
};

}  // namespace slamvdb::cli
