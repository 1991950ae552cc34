// Progress reporting shared by the cooker and the tools: a callback that gets a fraction in
// [0, 1] and the current stage name and returns false to cancel, plus a terminal progress bar.
#pragma once
#include <chrono>
#include <functional>
#include <string>
#include <string_view>

namespace terrain {

// Return false to ask the caller to stop (it then returns Error::cancelled).
using ProgressFn = std::function<bool(double fraction, std::string_view stage)>;

// Maps a sub-step's [0, 1] into [lo, hi] of `parent` (parent may be empty: the result then
// always returns true).
ProgressFn scaled_progress(ProgressFn parent, double lo, double hi);

// True when stderr is an interactive terminal.
bool stderr_is_terminal();

// A one-line bar on stderr ("stage  [#####.....]  42%  12.3 s"), redrawn at most ~10 times a
// second. Silent when disabled or when stderr is not a terminal, so logs and pipes stay clean.
// Not thread-safe: call it from one thread (wrap it if workers report).
class TerminalProgress {
 public:
  explicit TerminalProgress(bool enabled = true);
  ~TerminalProgress();  // calls done()
  TerminalProgress(const TerminalProgress&) = delete;
  TerminalProgress& operator=(const TerminalProgress&) = delete;

  bool update(double fraction, std::string_view stage);  // always returns true
  // Draws 100 % and ends the line (only if something was drawn).
  void done();
  bool active() const { return active_; }
  // A ProgressFn bound to this bar (the bar must outlive it).
  ProgressFn callback();

 private:
  bool active_ = false;
  bool drawn_ = false;
  double last_fraction_ = -1;
  std::string last_stage_;
  std::chrono::steady_clock::time_point start_, last_draw_;
  void draw(double fraction, std::string_view stage);
};

}  // namespace terrain
