#pragma once
// `kestrel farm check`: are all frames of a farm plan written and complete? Uses the writer's own
// completeness rule (ExrWriter::frameWritten: magic, a header OpenEXR parses, every chunk present,
// the data matching the writer's checksum; a truncated or corrupted file is broken), checks each
// output's provenance against the plan's graph and parameters (a foreign frame names what
// differs), and reads each task's wall time and outcome from its log.
#include <string>

#include "FarmPlan.h"

namespace kestrel::cli {

/// What a task's log says about its runs (`kestrel run` ends each with a "run finished" line).
struct TaskLog {
    bool found = false;      ///< the log file exists
    int attempts = 0;        ///< runs that reached frame 1 (a re-queued task appends)
    int exitCode = -1;       ///< of the last of them
    int written = 0;         ///< frames the last of them wrote
    double wallSeconds = 0;  ///< of the last of them
    std::string lastError;   ///< the last "error:" line, if any
};
TaskLog readTaskLog(const std::string& path);

/// Prints the missing and broken frames, each task's state and wall time, and the tasks to
/// re-run. Returns 0 when every frame is complete, 1 otherwise. Throws Error or GraphError when
/// the plan's graph cannot be prepared (exit 2).
int checkPlan(const FarmPlan& plan);

}  // namespace kestrel::cli
