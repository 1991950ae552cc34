// Shared by the command-line tools only (terrain-cook, terrain-inspect, terrain-view; needs CLI11):
// numeric flag checks with short messages ("--tolerance: must be > 0, got -1" instead of CLI11's
// "not in range 0.000000 to 1797693134862315..."), the exit-code footer of every --help, the line
// reader of the text files the tools take, and the last-resort guard that keeps exceptions from escaping main().
#pragma once
#include <CLI/CLI.hpp>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <istream>
#include <new>
#include <string>

namespace terrain::cli {

// Exit codes of all three tools (README "Exit codes"); terrain-view adds 77 (no Vulkan device).
inline constexpr const char* kExitCodes =
    "Exit codes: 0 ok, 1 failure (bad data, I/O, out of memory), 2 usage error (bad flag or argument).";

// Parses all of `text` as a double ("nan" and "inf" parse; the checks decide).
inline bool parse_number(const std::string& text, double& v) {
  const char* b = text.data();
  const char* e = b + text.size();
  if (b != e && *b == '+') ++b;
  const auto [p, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && p == e;
}

// A validator that accepts a number for which `ok` holds; otherwise "must be <rule>, got <text>".
inline CLI::Validator number_check(const std::string& rule, std::function<bool(double)> ok) {
  return CLI::Validator(
      [rule, ok](std::string& text) -> std::string {
        double v = 0;
        if (!parse_number(text, v)) return "expects a number, got '" + text + "'";
        if (!ok(v)) return "must be " + rule + ", got " + text;
        return {};
      },
      rule);
}

inline CLI::Validator positive() {
  return number_check("> 0", [](double v) { return std::isfinite(v) && v > 0; });
}
inline CLI::Validator finite() {
  return number_check("a finite number", [](double v) { return std::isfinite(v); });
}
// lo <= v <= hi, shown as "lo..hi".
inline CLI::Validator in_range(double lo, double hi) {
  char text[64];
  std::snprintf(text, sizeof(text), "%g..%g", lo, hi);
  return number_check(text, [lo, hi](double v) { return v >= lo && v <= hi; });
}
// Integers lo..hi (rejects 1.5).
inline CLI::Validator int_range(long long lo, long long hi) {
  const std::string rule = "an integer " + std::to_string(lo) + ".." + std::to_string(hi);
  return number_check(rule, [lo, hi](double v) { return v >= double(lo) && v <= double(hi) && v == std::floor(v); });
}

// Reads the next line of a text input the tools take (point files, camera paths) with its '#'
// comment cut off; `number` counts the lines read, for messages. False at the end of `in`.
inline bool next_line(std::istream& in, std::string& line, int& number) {
  if (!std::getline(in, line)) return false;
  ++number;
  if (const auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
  return true;
}

// Runs `body` and turns anything it throws into a message and exit 1: nothing escapes main()
// (an uncaught exception aborts with 134 and no explanation).
inline int guarded_main(const char* tool, const std::function<int()>& body) {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "%s: out of memory (an allocation failed; the input or the flags need more memory than this "
                 "machine or its limit allows)\n", tool);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: internal error: %s\n", tool, e.what());
  } catch (...) {
    std::fprintf(stderr, "%s: internal error (unknown exception)\n", tool);
  }
  return 1;
}

}  // namespace terrain::cli
