// The current time in UTC as ISO 8601 ("2026-11-24T19:45:16Z"): the `created` attribute of every
// file the project writes, a lock file's "since" line, a registration's date.
#pragma once

#include <string>

namespace pbdbench {

std::string utc_now();

}  // namespace pbdbench
