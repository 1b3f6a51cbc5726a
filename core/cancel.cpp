#include "core/cancel.hpp"

#include <atomic>

namespace pbdbench {

namespace {
std::atomic<bool> g_cancel{false};
static_assert(std::atomic<bool>::is_always_lock_free, "request_cancel() must be async-signal-safe");
}  // namespace

void request_cancel() noexcept { g_cancel.store(true, std::memory_order_relaxed); }
bool cancel_requested() noexcept { return g_cancel.load(std::memory_order_relaxed); }
void clear_cancel() noexcept { g_cancel.store(false, std::memory_order_relaxed); }

void throw_if_cancelled(const char* where) {
  if (cancel_requested()) throw Cancelled(std::string("interrupted in ") + where);
}

}  // namespace pbdbench
