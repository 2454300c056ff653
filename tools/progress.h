#pragma once
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>

#include <unistd.h>

namespace mvtwin::tools {

/// A progress line on stderr for a simulation's (t, duration) callback: rewritten in place at
/// most five times a second on a terminal, one line per 10 % otherwise (logs, CI).
inline std::function<void(double, double)> progress_line(const std::string& label) {
  struct State {
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now(), last;
    int decile = -1;
    bool tty = isatty(fileno(stderr)) != 0;
  };
  auto st = std::make_shared<State>();
  return [st, label](double t, double duration) {
    const auto now = std::chrono::steady_clock::now();
    const double frac = duration > 0 ? t / duration : 1.0;
    const double elapsed = std::chrono::duration<double>(now - st->start).count();
    const bool done = frac >= 1.0 - 1e-9;
    if (st->tty) {
      if (!done && now - st->last < std::chrono::milliseconds(200)) return;
      st->last = now;
      std::fprintf(stderr, "\r%s t = %.3f / %.3f s (%3.0f %%), %.1f s elapsed%s", label.c_str(), t,
                   duration, 100.0 * frac, elapsed, done ? "\n" : "");
    } else {
      const int decile = static_cast<int>(10.0 * frac + 1e-9);
      if (decile == st->decile) return;
      st->decile = decile;
      std::fprintf(stderr, "%s t = %.3f / %.3f s (%d %%), %.1f s elapsed\n", label.c_str(), t,
                   duration, 10 * decile, elapsed);
    }
    std::fflush(stderr);
  };
}

/// Writes one counted progress line on stderr ("[cohort] 3/25 (made 3, ...)"): rewritten in
/// place on a terminal, one line each otherwise (a log gets lines, not "\r"-joined text).
inline bool stderr_is_tty() {
  static const bool tty = isatty(fileno(stderr)) != 0;
  return tty;
}

inline void count_line(const std::string& text, bool last) {
  if (stderr_is_tty())
    std::fprintf(stderr, "\r%s%s", text.c_str(), last ? "\n" : "");
  else
    std::fprintf(stderr, "%s\n", text.c_str());
  std::fflush(stderr);
}

}  // namespace mvtwin::tools
