// SIGINT / SIGTERM: a flag that the commands poll between units of work (tools/commands.hpp).
#include <csignal>

#include "tools/commands.hpp"

namespace {

volatile std::sig_atomic_t interrupted = 0;

extern "C" void on_signal(int) { interrupted = 1; }

}  // namespace

namespace scout::tools {

void install_interrupt_handler() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

bool interrupt_requested() { return interrupted != 0; }

void throw_if_interrupted() {
  if (interrupted) throw Interrupted{};
}

}  // namespace scout::tools
