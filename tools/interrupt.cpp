// SIGINT / SIGTERM: a flag behind the process's stop token, which commands poll between units of
// work (tools/commands.hpp, core/stop.hpp).
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

const core::StopToken& interrupt_token() {
  static const core::StopToken token([] { return interrupted != 0; });
  return token;
}

}  // namespace scout::tools
