// The command-line tools' progress bar on stderr (terrain-cook, terrain-inspect, terrain-export),
// driven through a terrain::ProgressFn (terrain/progress.h).
#pragma once
#include <chrono>
#include <string>
#include <string_view>

#include "terrain/progress.h"

namespace terrain {

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
