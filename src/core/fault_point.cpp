#include "core/fault_point.h"

#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <cstring>
#include <string>

namespace raylod {

void fault_point(const char* name) {
  static const std::string armed = [] {
    const char* v = std::getenv("RAYLOD_FAULT_POINT");
    return std::string(v ? v : "");
  }();
  if (armed.empty() || armed != name) return;
  // One line on stderr (write(2): no buffering to lose), then as kill -9.
  const std::string line = std::string("raylod: fault point ") + name + ": SIGKILL\n";
  (void)!::write(2, line.data(), line.size());
  std::raise(SIGKILL);
}

}  // namespace raylod
