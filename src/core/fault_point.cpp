#include "core/fault_point.h"

#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <cstring>
#include <string>

namespace raylod {

bool fault_point(const char* name) {
  static const std::string armed = [] {
    const char* v = std::getenv("RAYLOD_FAULT_POINT");
    return std::string(v ? v : "");
  }();
  if (armed.empty() || armed.compare(0, std::strlen(name), name) != 0) return false;
  const std::string rest = armed.substr(std::strlen(name));
  if (rest == ":error") return true;
  if (!rest.empty()) return false;
  // One line on stderr (write(2): no buffering to lose), then as kill -9.
  const std::string line = std::string("raylod: fault point ") + name + ": SIGKILL\n";
  (void)!::write(2, line.data(), line.size());
  std::raise(SIGKILL);
  return false;
}

}  // namespace raylod
