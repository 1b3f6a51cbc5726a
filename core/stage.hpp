// What the program is doing, in a few words ("measuring the initial state", "writing the
// ParaView data"), set at the major steps of a run and an export: a failure that does not say
// where it happened (std::bad_alloc) is reported with it by the command line (app/main.cpp).
//
// Process-wide on purpose, as core/cancel.hpp's flag: the out-of-memory report is made by the
// command line's last catch, which sees no solver or runner. The texts are string literals (a
// pointer is all that is stored, so setting it allocates nothing).
#pragma once

#include <atomic>

namespace pbdbench {

inline std::atomic<const char*> g_stage{"starting"};

inline void set_stage(const char* what) noexcept { g_stage.store(what, std::memory_order_relaxed); }
inline const char* current_stage() noexcept { return g_stage.load(std::memory_order_relaxed); }

}  // namespace pbdbench
