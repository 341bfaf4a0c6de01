#include "core/fault_injection.hpp"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <string>

namespace scout::core {

namespace {

struct Target {
  std::string point;  // empty: no fault injection
  long nth = 0;
  std::atomic<long> reached{0};
};

Target& target() {
  static Target t;
  static const bool parsed = [] {
    if (const char* spec = std::getenv("SCOUT_FAULT_KILL_AT")) {
      const std::string text(spec);
      const auto colon = text.rfind(':');
      if (colon != std::string::npos && colon > 0) {
        t.point = text.substr(0, colon);
        t.nth = std::atol(text.c_str() + colon + 1);
      }
    }
    return true;
  }();
  (void)parsed;
  return t;
}

}  // namespace

void fault_point(const char* point) {
  Target& t = target();
  if (t.point.empty() || t.point != point) return;
  if (t.reached.fetch_add(1) + 1 == t.nth) ::kill(::getpid(), SIGKILL);
}

}  // namespace scout::core
