#pragma once
// A progress line on stderr for the long commands (eval, report): what is being done, how much of
// it, how fast and how long is left, at most every few seconds, so that a long evaluation never
// looks hung. Stdout keeps only the results.
#include <string>

namespace scout::tools {

/// "42 s", "4 min 30 s", "2 h 5 min"; "?" for a negative, non-finite or absurd (> 10^7 s) figure.
std::string format_duration(double seconds);

class ProgressLine {
 public:
  /// `command` prefixes every line ("scout eval"); `unit` names what is counted ("digits").
  ProgressLine(std::string command, std::string unit, double every_s = 10.0);

  /// Reports `done` of `total` units after `seconds`, with `what` ("run 3 of 20"), when at least
  /// the period has passed since the last line (or at the end: done == total).
  void update(const std::string& what, long done, long total, double seconds);

  /// The line update() prints, without its time check: "scout eval: run 3 of 20: 12000 of 90000
  /// rollouts (13 %), 312 rollouts/s, about 4 min 30 s left".
  static std::string format(const std::string& command, const std::string& unit, const std::string& what, long done,
                            long total, double seconds);

 private:
  std::string command_, unit_;
  double every_s_;
  double last_s_ = 0;
};

}  // namespace scout::tools
