#include "tools/progress.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <utility>

namespace scout::tools {

std::string format_duration(double seconds) {
  if (!(seconds >= 0) || seconds > 1e7) return "?";
  const auto s = static_cast<long>(std::lround(seconds));
  if (s < 60) return fmt::format("{} s", s);
  if (s < 3600) return fmt::format("{} min {} s", s / 60, s % 60);
  return fmt::format("{} h {} min", s / 3600, s % 3600 / 60);
}

ProgressLine::ProgressLine(std::string command, std::string unit, double every_s)
    : command_(std::move(command)), unit_(std::move(unit)), every_s_(every_s) {}

void ProgressLine::update(const std::string& what, long done, long total, double seconds) {
  if (done < total && seconds - last_s_ < every_s_) return;
  last_s_ = seconds;
  std::fprintf(stderr, "%s\n", format(command_, unit_, what, done, total, seconds).c_str());
  std::fflush(stderr);
}

std::string ProgressLine::format(const std::string& command, const std::string& unit, const std::string& what,
                                 long done, long total, double seconds) {
  std::string line = fmt::format("{}: {}{}{} of {} {}", command, what, what.empty() ? "" : ": ", done, total, unit);
  if (total > 0) line += fmt::format(" ({} %)", done * 100 / total);
  if (done > 0 && seconds > 0) {
    const double rate = static_cast<double>(done) / seconds;
    line += fmt::format(", {:.0f} {}/s", rate, unit);
    if (done < total)
      line += ", about " + format_duration(static_cast<double>(total - done) / rate) + " left";
    else
      line += ", " + format_duration(seconds);
  }
  return line;
}

}  // namespace scout::tools
