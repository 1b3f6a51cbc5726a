// Slurm job arrays for the commands that make many runs (paper, claims, regress, sweep).
//
// `pbdbench <command> ... --slurm N` writes, beside the run files, in <run files>/slurm/:
//   <command>.array.sbatch   the job array: task i runs `pbdbench <command> ... --shard i/N`
//   <command>.merge.sbatch   the merge: `pbdbench <command> ... --merge N`, which checks that
//                            every shard finished its runs (else it fails, listing them) and
//                            writes the report; it never makes a run itself
//   submit.sh                the command that wrote them (less --force): running it again
//                            submits only the shards with runs left, and a new merge
// and submits the array, then the merge after it (afterany: the merge runs whatever became of
// the tasks, so that a failure is reported rather than left pending). Every option of the
// command is carried into both jobs (the command line as typed, less the Slurm options), the
// jobs run in the folder pbdbench was called from, and their logs go to the same slurm/ folder.
// Site settings: sbatch options (--slurm-opt '--time=02:00:00 --partition=short') and a template
// file (its #SBATCH lines, and the shell lines that set up the environment: module load ...).
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace pbdbench::slurm {

// The cores this process may use: its CPU affinity (what Slurm's task/affinity or cgroups give a
// task; a whole machine outside Slurm), and no more than $SLURM_CPUS_PER_TASK when that is set.
// At least 1.
int allocated_cpus();

// What a site needs of every job: sbatch options, one #SBATCH line each, and shell lines run
// before the command (environment modules, a virtual environment, exports).
struct SiteSettings {
  std::vector<std::string> directives;  // "--time=02:00:00", "--partition=short", "-A proj"
  std::vector<std::string> setup;       // "module load hdf5/1.10"
};

// From --slurm-opt texts (each split at blanks into options: "--time=1:00:00 --mem=4G" is two;
// an option's value may follow it as the next word, "-p short") and a template file ("" for
// none): its #SBATCH lines are directives, its other lines that are not blank or comments are
// setup. Throws config::ConfigError (bad input, exit 2) naming the option, or the template's file
// and line: a word that is not an option, an option pbdbench sets itself (--array, --output,
// --error, --dependency, --parsable, --wrap, --chdir, and the older --workdir and -P) in any
// spelling sbatch accepts (an unambiguous prefix, --out=x; a short option, alone or in a group,
// -Ho x), a control character, or a template that cannot be read.
SiteSettings site_settings(const std::vector<std::string>& options, const std::filesystem::path& template_file);

// Two job scripts of one command.
struct Jobs {
  std::string command;                  // paper, claims, regress or sweep (job and file names)
  std::filesystem::path dir;            // the scripts and the logs (<run files>/slurm)
  std::filesystem::path workdir;        // where the jobs run (the folder pbdbench was called from)
  std::filesystem::path executable;     // the pbdbench binary (on a file system the nodes see)
  std::vector<std::string> args;        // the command's arguments (the Slurm options removed)
  int shards = 1;
  std::vector<std::pair<std::string, std::string>> environment;  // exported in both jobs
};

// The array: task i runs `executable args... --shard i/N` with the allocation's cores; the merge:
// `executable args... --merge N`. Both check first that the binary exists on the node.
std::string array_script(const Jobs& jobs, const SiteSettings& site);
std::string merge_script(const Jobs& jobs, const SiteSettings& site);

struct ScriptFiles {
  std::filesystem::path array, merge, submit;
};
// Writes the two scripts and submit.sh (which reruns `submit_command` in jobs.workdir) to
// jobs.dir, creating it (Slurm does not create the folder of a log).
ScriptFiles write_scripts(const Jobs& jobs, const SiteSettings& site, const std::vector<std::string>& submit_command);

// Submits the array's tasks `shards` (all of them, or those with runs left; none: only the merge)
// with `sbatch --parsable`, then the merge with --dependency=afterany on the array. Returns the
// job ids (the array's "" when none was submitted). Throws std::runtime_error with sbatch's
// message when sbatch is missing or refuses.
struct Submitted {
  std::string array_job, merge_job;
};
Submitted submit(const ScriptFiles& files, const std::vector<int>& shards);

// The arguments without the Slurm options (--slurm, --slurm-opt, --slurm-template, --no-submit),
// in both forms (--slurm 4, --slurm=4).
std::vector<std::string> strip_slurm_options(const std::vector<std::string>& args);

// `text` quoted for bash ('...', a quote inside as '\''); bare when it is only safe characters.
// Single quotes keep every character but a newline's meaning in a comment, hence the next.
std::string shell_quote(const std::string& text);

// Throws config::ConfigError (bad input, exit 2) naming `what` when `value` holds a newline or
// another control character (below 0x20, or 0x7f). Every value written into a job script passes
// here first (array_script, merge_script and write_scripts check them all): quoted for bash, a
// newline is still the end of a comment line, and sbatch reads #SBATCH lines one line at a time.
void check_script_value(const std::string& value, const std::string& what);

// `text` as one argument of an #SBATCH line: sbatch splits those lines at blanks, ends them at an
// unquoted '#', and takes '\' as an escape inside quotes as well, so it is written "..." with '"'
// and '\' escaped by a '\'; bare when it is only safe characters.
std::string sbatch_quote(const std::string& text);

}  // namespace pbdbench::slurm
