#include "harness/slurm.hpp"

#include <fcntl.h>
#include <sched.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include <fmt/format.h>

#include "config/config.hpp"
#include "harness/shards.hpp"
#include "runfile/build_info.hpp"

extern char** environ;

namespace pbdbench::slurm {

namespace fs = std::filesystem;

namespace {

using config::ConfigError;
using config::Source;

// sbatch reads its options with getopt_long: a long option may be spelled by any prefix of its
// name that no other option shares (--out=x is --output=x, --dep=... is --dependency=...), and
// short options may be grouped (-Ho x is -H -o x). Each word a site gives is therefore read as
// sbatch reads it before it is compared with the options pbdbench writes itself.

// The short options of sbatch that take no argument: a group goes on after them. Any other letter
// takes the rest of the word (or the next word) as its argument, or is refused by sbatch.
constexpr std::string_view kShortFlags = "hHIkOQsuvVW";

// The options pbdbench writes itself, long and short: a site may not set them in any spelling.
// (--workdir and -P: older names of --chdir and --dependency.)
struct Owned {
  const char* name;
  char letter;
};
constexpr Owned kOwned[] = {{"--array", 'a'},     {"--output", 'o'},   {"--error", 'e'},
                            {"--dependency", 'd'}, {"--parsable", 0},   {"--wrap", 0},
                            {"--chdir", 'D'},      {"--workdir", 0},    {"", 'P'}};

// The long option `word` spells, among `names` ("--out=x" -> "--output"), or "": the name before
// any '=' equal to one of them, or a prefix of one with at least one letter after the dashes.
std::string long_option(const std::string& word, std::initializer_list<std::string_view> names) {
  if (word.rfind("--", 0) != 0) return "";
  const std::string name = word.substr(0, word.find('='));
  if (name.size() < 3) return "";
  for (std::string_view n : names)
    if (n.size() >= name.size() && n.substr(0, name.size()) == name) return std::string(n);
  return "";
}

// The short options of a group ("-Hc4" -> "Hc"): the flags, then the first letter that takes an
// argument (the rest of the word is its value).
std::string short_options(const std::string& word) {
  if (word.size() < 2 || word[0] != '-' || word[1] == '-') return "";
  std::string letters;
  for (size_t k = 1; k < word.size(); ++k) {
    letters += word[k];
    if (kShortFlags.find(word[k]) == std::string_view::npos) break;
  }
  return letters;
}

// The option pbdbench writes itself that `word` spells, as its long name ("" when none).
std::string ours(const std::string& word) {
  for (const Owned& o : kOwned)
    if (*o.name != '\0' && !long_option(word, {o.name}).empty()) return o.name;
  for (char c : short_options(word))
    for (const Owned& o : kOwned)
      if (o.letter == c) return std::string("-") + c + (*o.name != '\0' ? std::string(" (") + o.name + ")" : "");
  return "";
}

bool sets(const std::vector<std::string>& directives, const char* long_name, char letter) {
  for (const std::string& d : directives) {
    const std::string word = d.substr(0, d.find(' '));
    if (!long_option(word, {long_name}).empty() || short_options(word).find(letter) != std::string::npos) return true;
  }
  return false;
}

void check_directive(const std::string& directive, const Source& where) {
  if (directive.empty() || directive[0] != '-' || directive == "-" || directive.rfind("--", 0) == 0 && directive.size() == 2)
    throw ConfigError(where, "", "'" + directive + "' is not an sbatch option (they start with - and name one)");
  check_script_value(directive, where.file);
  const std::string word = directive.substr(0, directive.find(' '));
  if (const std::string owned = ours(word); !owned.empty())
    throw ConfigError(where, "",
                      "'" + word + "' is " + owned + " to sbatch, which pbdbench sets itself (the array, the logs "
                      "beside the results, the merge's dependency, the working folder); leave it out");
}

std::vector<std::string> words(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

// A value's control characters written out: "x\ntouch y" for a newline.
std::string escaped(const std::string& value) {
  std::string out;
  for (unsigned char c : value) {
    if (c == '\n') out += "\\n";
    else if (c == '\t') out += "\\t";
    else if (c == '\r') out += "\\r";
    else if (c < 0x20 || c == 0x7f) out += fmt::format("\\x{:02x}", static_cast<unsigned>(c));
    else out += static_cast<char>(c);
  }
  return out;
}

// The logs' folder as a file name pattern of --output: '%' starts a pattern (%A, %a, %j), "%%" is
// a '%' of the name.
std::string log_pattern(const fs::path& dir) {
  std::string out;
  for (char c : dir.string()) out += c == '%' ? std::string("%%") : std::string(1, c);
  return out;
}

// Every value that goes into the scripts, before any is written.
void check_jobs(const Jobs& jobs) {
  check_script_value(jobs.command, "the command's name");
  check_script_value(jobs.dir.string(), "the folder of the run files and the Slurm logs");
  check_script_value(jobs.workdir.string(), "the working folder (where the jobs run)");
  check_script_value(jobs.executable.string(), "the pbdbench executable's path");
  for (size_t k = 0; k < jobs.args.size(); ++k)
    check_script_value(jobs.args[k], fmt::format("argument {} of the command line", k + 1));
  for (const auto& [name, value] : jobs.environment) {
    check_script_value(name, "an environment variable's name");
    check_script_value(value, "$" + name);
  }
}

// `what`: comment lines saying what the job does.
std::string header(const Jobs& jobs, const std::string& what) {
  std::string h = "#!/bin/bash\n";
  h += fmt::format("# Generated by `pbdbench {} ... --slurm {}` (pbdbench {}, commit {}).\n", jobs.command, jobs.shards,
                   build_info().version, build_info().git_commit);
  h += what;
  h += fmt::format("# Submit the array and the merge after it (only the shards with runs left): bash {}\n",
                   shell_quote((jobs.dir / "submit.sh").string()));
  return h;
}

std::string body(const Jobs& jobs, const SiteSettings& site, const std::string& tail) {
  std::string b;
  if (!site.setup.empty()) {
    b += "# Site setup (--slurm-template)\n";
    for (const std::string& line : site.setup) b += line + "\n";
  }
  b += "set -euo pipefail\n";
  for (const auto& [name, value] : jobs.environment) b += fmt::format("export {}={}\n", name, shell_quote(value));
  b += fmt::format("bin={}\n", shell_quote(jobs.executable.string()));
  b += "if [[ ! -x \"$bin\" ]]; then\n"
       "  echo \"pbdbench: $bin is not on $(hostname): install pbdbench where every node sees it \"\\\n"
       "       \"(cmake --install build --prefix /a/shared/folder)\" >&2\n"
       "  exit 1\n"
       "fi\n";
  b += "echo \"pbdbench on $(hostname), job ${SLURM_JOB_ID:-none}, $(nproc) cores: $(date -u +%FT%TZ)\"\n";
  std::string command = "\"$bin\"";
  for (const std::string& a : jobs.args) command += fmt::format(" {}", shell_quote(a));
  b += command + " " + tail + "\n";
  return b;
}

// Runs argv (PATH searched), returns its exit status and what it printed (stdout and stderr).
std::pair<int, std::string> capture(const std::vector<std::string>& args) {
  int fds[2];
  if (pipe(fds) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDERR_FILENO);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  std::vector<std::string> copy = args;
  std::vector<char*> argv;
  for (std::string& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(fds[1]);
  if (rc != 0) {
    close(fds[0]);
    throw std::runtime_error(fmt::format("cannot start {}: {} (is Slurm's client installed here?)", args[0],
                                         std::strerror(rc)));
  }
  std::string output;
  char buffer[4096];
  for (ssize_t n; (n = read(fds[0], buffer, sizeof buffer)) != 0;) {
    if (n < 0) {
      if (errno == EINTR) continue;
      break;
    }
    output.append(buffer, static_cast<size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128, output};
}

std::string job_id(const std::string& parsable) {
  std::string id = parsable.substr(0, parsable.find_first_of(";\n"));
  while (!id.empty() && (id.back() == ' ' || id.back() == '\r')) id.pop_back();
  return id;
}

void write_file(const fs::path& path, const std::string& text, bool executable) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
  f.close();
  if (!f) throw std::runtime_error("cannot write " + path.string());
  if (executable) fs::permissions(path, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                                  fs::perm_options::add);
}

}  // namespace

int allocated_cpus() {
  int cpus = 0;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) cpus = CPU_COUNT(&set);
  if (cpus < 1) cpus = static_cast<int>(sysconf(_SC_NPROCESSORS_ONLN));
  if (const char* env = std::getenv("SLURM_CPUS_PER_TASK"); env != nullptr && *env != '\0') {
    char* end = nullptr;
    const long n = std::strtol(env, &end, 10);
    if (end != env && *end == '\0' && n >= 1 && n < cpus) cpus = static_cast<int>(n);
  }
  return cpus < 1 ? 1 : cpus;
}

SiteSettings site_settings(const std::vector<std::string>& options, const fs::path& template_file) {
  SiteSettings site;
  auto add_words = [&](const std::vector<std::string>& ws, const Source& where) {
    for (size_t k = 0; k < ws.size(); ++k) {
      std::string d = ws[k];
      // "-p short", "-Hp short": a short option's value may be the next word.
      const std::string letters = short_options(d);
      if (!letters.empty() && letters.size() + 1 == d.size() && kShortFlags.find(letters.back()) == std::string_view::npos &&
          k + 1 < ws.size() && ws[k + 1][0] != '-')
        d += " " + ws[++k];
      check_directive(d, where);
      site.directives.push_back(d);
    }
  };
  if (!template_file.empty()) {
    std::ifstream in(template_file);
    if (!in) throw ConfigError(Source{template_file.string(), 0}, "", "cannot read the Slurm template");
    int line_no = 0;
    for (std::string line; std::getline(in, line);) {
      ++line_no;
      const size_t first = line.find_first_not_of(" \t");
      if (first == std::string::npos) continue;
      const std::string text = line.substr(first);
      if (text.rfind("#SBATCH", 0) == 0) {
        std::string rest = text.substr(7);
        if (const size_t hash = rest.find(" #"); hash != std::string::npos) rest = rest.substr(0, hash);
        add_words(words(rest), Source{template_file.string(), line_no});
      } else if (text[0] != '#') {
        site.setup.push_back(line);
      }
    }
  }
  for (const std::string& o : options) add_words(words(o), Source{"--slurm-opt " + o, 0});
  return site;
}

std::string array_script(const Jobs& jobs, const SiteSettings& site) {
  check_jobs(jobs);
  std::string s = header(jobs, fmt::format("# The runs as a job array of {} tasks: task i makes shard i (`--shard i/{}`) with the\n"
                                           "# cores of its allocation; {}.merge.sbatch merges them.\n",
                                           jobs.shards, jobs.shards, jobs.command));
  s += fmt::format("#SBATCH --job-name=pbdbench-{}\n", jobs.command);
  s += fmt::format("#SBATCH --array=0-{}\n", jobs.shards - 1);
  if (!sets(site.directives, "--ntasks", 'n')) s += "#SBATCH --ntasks=1\n";
  if (!sets(site.directives, "--cpus-per-task", 'c')) s += "#SBATCH --cpus-per-task=1\n";
  s += "#SBATCH --chdir=" + sbatch_quote(jobs.workdir.string()) + "\n";
  s += "#SBATCH --output=" + sbatch_quote(log_pattern(jobs.dir) + "/" + jobs.command + "-%A_%a.log") + "\n";
  for (const std::string& d : site.directives) s += "#SBATCH " + d + "\n";
  return s + body(jobs, site, fmt::format("--shard \"${{SLURM_ARRAY_TASK_ID}}/{}\"", jobs.shards));
}

std::string merge_script(const Jobs& jobs, const SiteSettings& site) {
  check_jobs(jobs);
  std::string s = header(jobs, fmt::format("# The merge of the {} shards of {}.array.sbatch: it checks that every run is finished\n"
                                           "# (else it fails, naming the shards and how to resubmit them) and writes the report.\n"
                                           "# It makes no run itself.\n",
                                           jobs.shards, jobs.command));
  s += fmt::format("#SBATCH --job-name=pbdbench-{}-merge\n", jobs.command);
  s += "#SBATCH --ntasks=1\n#SBATCH --cpus-per-task=1\n";
  s += "#SBATCH --chdir=" + sbatch_quote(jobs.workdir.string()) + "\n";
  s += "#SBATCH --output=" + sbatch_quote(log_pattern(jobs.dir) + "/" + jobs.command + "-merge-%j.log") + "\n";
  for (const std::string& d : site.directives)
    if (!sets({d}, "--cpus-per-task", 'c') && !sets({d}, "--ntasks", 'n')) s += "#SBATCH " + d + "\n";
  return s + body(jobs, site, fmt::format("--merge {}", jobs.shards));
}

ScriptFiles write_scripts(const Jobs& jobs, const SiteSettings& site, const std::vector<std::string>& submit_command) {
  check_jobs(jobs);
  for (size_t k = 0; k < submit_command.size(); ++k)
    check_script_value(submit_command[k], fmt::format("argument {} of the command line", k));
  fs::create_directories(jobs.dir);
  ScriptFiles files{jobs.dir / (jobs.command + ".array.sbatch"), jobs.dir / (jobs.command + ".merge.sbatch"),
                    jobs.dir / "submit.sh"};
  write_file(files.array, array_script(jobs, site), false);
  write_file(files.merge, merge_script(jobs, site), false);
  std::string submit = "#!/bin/bash\n";
  submit += fmt::format("# Submits `pbdbench {}` to Slurm again, as it was first submitted: only the shards whose runs\n"
                        "# are not all finished, then a new merge after them.\n",
                        jobs.command);
  submit += fmt::format("set -euo pipefail\ncd {}\nexec", shell_quote(jobs.workdir.string()));
  for (const std::string& a : submit_command) submit += fmt::format(" {}", shell_quote(a));
  write_file(files.submit, submit + "\n", true);
  return files;
}

Submitted submit(const ScriptFiles& files, const std::vector<int>& shards) {
  Submitted out;
  auto sbatch = [](std::vector<std::string> args) {
    args.insert(args.begin(), {"sbatch", "--parsable"});
    const auto [rc, output] = capture(args);
    if (rc != 0) throw std::runtime_error(fmt::format("sbatch refused (exit {}): {}", rc, output));
    const std::string id = job_id(output);
    if (id.empty()) throw std::runtime_error("sbatch printed no job id: " + output);
    return id;
  };
  std::vector<std::string> merge_args;
  if (!shards.empty()) {
    out.array_job = sbatch({"--array=" + array_list(shards), files.array.string()});
    merge_args.push_back("--dependency=afterany:" + out.array_job);
  }
  merge_args.push_back(files.merge.string());
  out.merge_job = sbatch(merge_args);
  return out;
}

std::vector<std::string> strip_slurm_options(const std::vector<std::string>& args) {
  std::vector<std::string> out;
  for (size_t k = 0; k < args.size(); ++k) {
    const std::string& a = args[k];
    if (a == "--no-submit") continue;
    bool dropped = false;
    for (const char* o : {"--slurm", "--slurm-opt", "--slurm-template"}) {
      if (a == o) {
        ++k;  // and its value
        dropped = true;
      } else if (a.rfind(std::string(o) + "=", 0) == 0) {
        dropped = true;
      }
    }
    if (!dropped) out.push_back(a);
  }
  return out;
}

void check_script_value(const std::string& value, const std::string& what) {
  for (size_t k = 0; k < value.size(); ++k) {
    const unsigned char c = static_cast<unsigned char>(value[k]);
    if (c >= 0x20 && c != 0x7f) continue;
    const std::string which = c == '\n' ? "a newline" : c == '\r' ? "a carriage return" : c == '\t' ? "a tab"
                                                      : fmt::format("the control character \\x{:02x}", static_cast<unsigned>(c));
    throw ConfigError(Source{what, 0}, "",
                      fmt::format("'{}' holds {} (at byte {}): a value that goes into a Slurm job script may hold no "
                                  "newline or other control character (a shell would read what follows it as a "
                                  "command); nothing was written",
                                  escaped(value), which, k));
  }
}

std::string sbatch_quote(const std::string& text) {
  if (!text.empty() && text.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
                                              "_-./=:,+@%") == std::string::npos)
    return text;
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string shell_quote(const std::string& text) {
  if (!text.empty() && text.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
                                              "_-./=:,+@%") == std::string::npos)
    return text;
  std::string out = "'";
  for (char c : text) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace pbdbench::slurm
