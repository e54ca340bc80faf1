#include "core/fault_point.h"

#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

namespace raylod {

bool fault_point(const char* name) {
  static const std::string armed = [] {
    const char* v = std::getenv("RAYLOD_FAULT_POINT");
    return std::string(v ? v : "");
  }();
  const std::string_view n(name);
  if (armed.empty() || std::string_view(armed).substr(0, n.size()) != n) return false;
  const std::string_view rest = std::string_view(armed).substr(n.size());
  if (rest == ":error") return true;
  if (!rest.empty()) return false;
  // One line on stderr (write(2): no buffering to lose), then as kill -9.
  const std::string line = std::string("raylod: fault point ") + name + ": SIGKILL\n";
  (void)!::write(2, line.data(), line.size());
  std::raise(SIGKILL);
  return false;
}

}  // namespace raylod
