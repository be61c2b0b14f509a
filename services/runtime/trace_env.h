// GODHAND_TRACE=1|2|3 -> the pipeline's diagnostic lines (PipelineParams::trace) on stderr. The
// environment is read here, in the services, never in core.
#pragma once

#include <cstdio>
#include <cstdlib>

#include "pipeline/stages.h"

namespace godhand::svc {

inline void traceFromEnvironment(PipelineParams* p) {
  const char* t = std::getenv("GODHAND_TRACE");
  p->trace = t ? std::atoi(t) : 0;
  if (p->trace > 0) p->trace_sink = [](const char* line) { std::fputs(line, stderr); };
}

}  // namespace godhand::svc
