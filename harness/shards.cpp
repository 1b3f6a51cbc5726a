#include "harness/shards.hpp"

#include <algorithm>
#include <map>
#include <numeric>
#include <stdexcept>

#include <fmt/format.h>

#include "runfile/build_info.hpp"
#include "runfile/run_file.hpp"

namespace pbdbench {

namespace fs = std::filesystem;

std::vector<int> deal_units(const std::vector<std::size_t>& sizes, int shards) {
  if (shards < 1) throw std::invalid_argument("deal_units: shards must be at least 1");
  std::vector<std::size_t> order(sizes.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return sizes[a] > sizes[b]; });
  std::vector<std::size_t> load(static_cast<std::size_t>(shards), 0);
  std::vector<int> out(sizes.size(), 0);
  for (std::size_t u : order) {
    const auto least = std::min_element(load.begin(), load.end());  // the first of the least loaded
    out[u] = static_cast<int>(least - load.begin());
    *least += std::max<std::size_t>(sizes[u], 1);
  }
  return out;
}

std::string run_state(const fs::path& file, const std::string& config_toml) {
  std::error_code ec;
  if (!fs::exists(file, ec)) return "missing";
  try {
    const RunFileData data = read_run_file(file, false);
    const std::string status = data.status();
    if (status == "incomplete" || status == "failed") return status;
    auto cfg = data.attributes.find("config");
    auto commit = data.attributes.find("git_commit");
    const bool same = cfg != data.attributes.end() && cfg->second == config_toml &&
                      commit != data.attributes.end() && commit->second == build_info().git_commit;
    if (status == "complete" || status == "exploded") return same ? "current" : "stale";
    return "incomplete";
  } catch (const std::exception&) {
    return "unreadable";
  }
}

std::string shard_name(int index, int count) { return fmt::format("shard {}/{}", index, count); }

std::string shard_numbering(int count) {
  if (count <= 1) return "counted from 0: 0/1 alone";
  return fmt::format("counted from 0: 0/{} to {}/{}", count, count - 1, count);
}

std::vector<int> shards_of(const std::vector<UnfinishedRun>& runs) {
  std::vector<int> out;
  for (const UnfinishedRun& r : runs) out.push_back(r.shard);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::string unfinished_report(const std::vector<UnfinishedRun>& runs, int shards, const std::string& next_steps) {
  std::map<int, std::vector<const UnfinishedRun*>> by_shard;
  for (const UnfinishedRun& r : runs) by_shard[r.shard].push_back(&r);
  std::string out = fmt::format("{} run{} of {} shard{} (of {}, {}) {} not finished; nothing was merged:\n",
                                runs.size(), runs.size() == 1 ? "" : "s", by_shard.size(),
                                by_shard.size() == 1 ? "" : "s", shards, shard_numbering(shards),
                                runs.size() == 1 ? "is" : "are");
  for (const auto& [shard, list] : by_shard) {
    out += fmt::format("  {}: {} run{}\n", shard_name(shard, shards), list.size(), list.size() == 1 ? "" : "s");
    constexpr size_t kShown = 10;  // per shard; index.json lists every run with its status
    for (size_t k = 0; k < list.size(); ++k) {
      if (k == kShown) {
        out += fmt::format("    ... and {} more (index.json beside the run files lists them all)\n", list.size() - k);
        break;
      }
      const UnfinishedRun* r = list[k];
      std::string why = r->state;
      if (r->state == "missing") why = "missing (no run file: the task did not reach it)";
      else if (r->state == "incomplete") why = "incomplete (interrupted: cancelled, timed out or killed)";
      else if (r->state == "failed") why = "failed";
      else if (r->state == "stale") why = "stale (a file of another configuration or build)";
      out += fmt::format("    {}: {}", r->label, why);
      fs::path log = r->file;
      log.replace_extension(".log");
      std::error_code ec;
      if (r->state != "missing" && fs::exists(log, ec)) out += fmt::format("; log {}", log.string());
      out += "\n";
    }
  }
  out += next_steps;
  return out;
}

std::string array_list(const std::vector<int>& shards) {
  std::string out;
  for (std::size_t i = 0; i < shards.size();) {
    std::size_t j = i;
    while (j + 1 < shards.size() && shards[j + 1] == shards[j] + 1) ++j;
    if (!out.empty()) out += ",";
    out += j == i ? std::to_string(shards[i]) : fmt::format("{}-{}", shards[i], shards[j]);
    i = j + 1;
  }
  return out;
}

}  // namespace pbdbench
