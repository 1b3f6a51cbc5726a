// Cancellation: a request to stop the run, made by a signal handler (SIGINT, SIGTERM) and
// polled by the loops that can take long inside one step (projection sweeps, Newton and CG
// iterations, the SUNDIALS callbacks), so that a step of minutes still stops within a second.
//
// This is the one piece of process-wide state in the library, on purpose: a signal reaches the
// process, not a solver. The solvers only read it; the command line sets it and the runner
// clears it at the start of a run.
#pragma once

#include <stdexcept>
#include <string>

namespace pbdbench {

// Thrown by throw_if_cancelled(); the runner records the run as interrupted (incomplete).
class Cancelled : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

void request_cancel() noexcept;  // async-signal-safe
bool cancel_requested() noexcept;
void clear_cancel() noexcept;

// Throws Cancelled ("interrupted in <where>") when a cancellation was requested. Not for code
// called back from C (SUNDIALS): there, return the library's failure code on cancel_requested().
void throw_if_cancelled(const char* where);

}  // namespace pbdbench
