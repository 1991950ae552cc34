// CPU clocks for stage timings (cook report, benchmarks). Stage times are CPU time, not wall time:
// on a loaded machine a preempted thread would otherwise charge other processes' time to the stage,
// and the budgets are per CPU-second. Each read is a system call: a few per node, not per sample.
#pragma once
#include <ctime>

namespace terrain {

inline double seconds_of_clock(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}
// The calling thread's CPU time (the cooker runs nodes on several threads).
inline double thread_cpu_seconds() { return seconds_of_clock(CLOCK_THREAD_CPUTIME_ID); }
// The whole process's CPU time, all threads.
inline double process_cpu_seconds() { return seconds_of_clock(CLOCK_PROCESS_CPUTIME_ID); }

}  // namespace terrain
