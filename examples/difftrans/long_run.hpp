// Long fits of the difftrans command: a progress meter (on a terminal one
// line redrawn in place with the stage, a bar, the iteration, the figures and
// the time left; elsewhere plain lines every few seconds), and SIGINT /
// SIGTERM handling that lets the running stage save its checkpoint before the
// program exits.
#pragma once

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <utility>
#include <sys/ioctl.h>
#include <unistd.h>

#include "command.hpp"

namespace difftrans::cli {

// ------------------------------------------------------------ interruption

namespace detail {
inline volatile std::sig_atomic_t stop_signal = 0;
// The first SIGINT / SIGTERM asks the stage to stop; the handler then steps
// aside, so a second one ends the program at once.
extern "C" inline void on_stop_signal(int sig) {
  stop_signal = sig;
  std::signal(sig, SIG_DFL);
}
}  // namespace detail

// Thrown by a stage that stopped on a signal after saving its checkpoint.
struct Interrupted : std::runtime_error {
  int signal;
  explicit Interrupted(int sig, const std::string& what) : std::runtime_error(what), signal(sig) {}
};

// While alive, SIGINT and SIGTERM only set a flag that stop_requested() reads.
class StopSignals {
 public:
  StopSignals() {
    detail::stop_signal = 0;
    previous_int_ = std::signal(SIGINT, detail::on_stop_signal);
    previous_term_ = std::signal(SIGTERM, detail::on_stop_signal);
  }
  ~StopSignals() {
    std::signal(SIGINT, previous_int_);
    std::signal(SIGTERM, previous_term_);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  void (*previous_int_)(int) = SIG_DFL;
  void (*previous_term_)(int) = SIG_DFL;
};

inline int stop_requested() { return int(detail::stop_signal); }

// Call between iterations, after the checkpoint is saved: throws Interrupted
// when a signal arrived, saying where the work is kept. A loop that decides
// whether to save from one reading of stop_requested() passes that reading
// as `sig`: a signal arriving between the decision and this call must not
// stop it with a message about a checkpoint it did not write.
inline void stop_if_requested(const std::string& stage, const std::string& kept, int sig = stop_requested()) {
  if (sig)
    throw Interrupted(sig, stage + ": stopped by " + (sig == SIGINT ? std::string("SIGINT") : std::string("SIGTERM")) +
                               "; " + kept + ". Run the same command again to go on from there.");
}

// ------------------------------------------------------------ progress

inline std::string clock_text(double seconds) {
  if (!(seconds >= 0.0) || seconds > 1e7) return "?";
  const long s = long(seconds + 0.5);
  char buf[32];
  if (s >= 3600) std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  else std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

class ProgressMeter {
 public:
  // `total` iterations of `stage`; a resumed fit starts at `first`, and the
  // time left is estimated from the iterations this process has run.
  ProgressMeter(std::string stage, int total, int first = 0)
      : stage_(std::move(stage)), total_(std::max(1, total)), first_(first), start_(clock::now()),
        last_(start_ - std::chrono::hours(1)) {}
  ~ProgressMeter() { finish(); }
  ProgressMeter(const ProgressMeter&) = delete;
  ProgressMeter& operator=(const ProgressMeter&) = delete;

  // After an iteration: `done` iterations are finished; `figures` says how
  // the fit stands (loss, IoR, ...).
  void update(int done, const std::string& figures) {
    const auto now = clock::now();
    const double since_last = seconds(now - last_);
    const bool end = done >= total_;
    last_figures_ = figures;
    last_done_ = done;
    if (terminal()) {
      if (!end && since_last < 0.1) return;
      draw(done, figures, now);
    } else {
      if (!end && done - first_ > 2 && since_last < plain_every) return;
      progress(stage_ + ": it " + std::to_string(done) + "/" + std::to_string(total_) + " " + figures + "  " +
               left_text(done, now));
    }
    last_ = now;
  }

  // Ends the terminal line with the last state (idempotent).
  void finish() {
    if (!terminal() || last_done_ < 0 || finished_) return;
    finished_ = true;
    progress(stage_ + ": it " + std::to_string(last_done_) + "/" + std::to_string(total_) + " " + last_figures_ +
             "  " + clock_text(seconds(clock::now() - start_)) + " elapsed");
  }

  static constexpr double plain_every = 2.0;  // seconds between plain lines

 private:
  using clock = std::chrono::steady_clock;
  static double seconds(clock::duration d) { return std::chrono::duration<double>(d).count(); }

  std::string left_text(int done, clock::time_point now) const {
    const int ran = done - first_;
    if (ran <= 0 || done >= total_) return done >= total_ ? "done" : "";
    return clock_text(seconds(now - start_) / ran * (total_ - done)) + " left";
  }

  void draw(int done, const std::string& figures, clock::time_point now) {
    int width = 100;
    winsize ws{};
    if (ioctl(STDERR_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 20) width = ws.ws_col;
    const int bar = 20, filled = std::min(bar, bar * std::max(0, done) / total_);
    std::string line = stage_ + " [" + std::string(std::size_t(filled), '#') + std::string(std::size_t(bar - filled), '.') +
                       "] " + std::to_string(done) + "/" + std::to_string(total_) + "  " + left_text(done, now) +
                       "  " + figures;
    if (int(line.size()) > width - 1) line.resize(std::size_t(width - 1));
    status_line(line);
  }

  std::string stage_;
  int total_, first_;
  clock::time_point start_, last_;
  std::string last_figures_;
  int last_done_ = -1;
  bool finished_ = false;
};

}  // namespace difftrans::cli
