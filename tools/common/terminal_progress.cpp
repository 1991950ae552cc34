#include "terminal_progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace terrain {

bool stderr_is_terminal() { return ::isatty(STDERR_FILENO) == 1; }

TerminalProgress::TerminalProgress(bool enabled)
    : active_(enabled && stderr_is_terminal()), start_(std::chrono::steady_clock::now()) {}

TerminalProgress::~TerminalProgress() { done(); }

bool TerminalProgress::update(double fraction, std::string_view stage) {
  if (!active_) return true;
  fraction = std::clamp(fraction, 0.0, 1.0);
  const auto now = std::chrono::steady_clock::now();
  const bool stage_changed = stage != last_stage_;
  if (!stage_changed && drawn_ && now - last_draw_ < std::chrono::milliseconds(100) && fraction < 1.0) return true;
  last_draw_ = now;
  if (stage_changed) last_stage_ = std::string(stage);
  draw(fraction, stage);
  return true;
}

void TerminalProgress::draw(double fraction, std::string_view stage) {
  constexpr int kWidth = 30;
  const int filled = int(fraction * kWidth + 0.5);
  char bar[kWidth + 1];
  for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
  bar[kWidth] = 0;
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  std::fprintf(stderr, "\r%-24.*s [%s] %3d%%  %.1f s\x1b[K", int(std::min<size_t>(stage.size(), 24)), stage.data(),
               bar, int(fraction * 100.0 + 0.5), seconds);
  std::fflush(stderr);
  drawn_ = true;
  last_fraction_ = fraction;
}

void TerminalProgress::done() {
  if (!active_ || !drawn_) return;
  draw(1.0, last_stage_);
  std::fputc('\n', stderr);
  std::fflush(stderr);
  drawn_ = false;
  active_ = false;
}

ProgressFn TerminalProgress::callback() {
  return [this](double fraction, std::string_view stage) { return update(fraction, stage); };
}

}  // namespace terrain
