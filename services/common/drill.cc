#include "common/drill.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

namespace godhand {

Drill parseDrill(const std::string& spec) {
  auto bad = [&](const std::string& why) {
    return std::invalid_argument("--kill '" + spec + "': " + why + " (expected SERVICE@SECONDS, SERVICE@Ss or SERVICE@fFRAME)");
  };
  const size_t at = spec.find('@');
  if (at == std::string::npos) throw bad("no '@'");
  Drill d;
  d.spec = spec;
  d.service = spec.substr(0, at);
  std::string when = spec.substr(at + 1);
  if (d.service.empty()) throw bad("no service");
  if (when.empty()) throw bad("no time");
  if (when[0] == 'f') {
    const std::string n = when.substr(1);
    if (n.empty() || n.find_first_not_of("0123456789") != std::string::npos || n.size() > 12) throw bad("bad frame");
    d.by_frame = true;
    d.frame = std::strtoull(n.c_str(), nullptr, 10);
    if (d.frame < 1) throw bad("frames start at 1");
    return d;
  }
  if (when.back() == 's') when.pop_back();
  if (when.empty() || when.find_first_not_of("0123456789.") != std::string::npos) throw bad("bad time");
  char* end = nullptr;
  errno = 0;
  d.seconds = std::strtod(when.c_str(), &end);
  if (!end || *end || errno != 0 || !std::isfinite(d.seconds) || d.seconds < 0.0 || d.seconds > 86400.0) throw bad("bad time");
  return d;
}

}  // namespace godhand
