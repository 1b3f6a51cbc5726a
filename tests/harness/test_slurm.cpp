// harness/slurm: site settings, the job scripts, the arguments carried into them, the cores of
// the allocation.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "config/config.hpp"
#include "harness/slurm.hpp"

namespace fs = std::filesystem;
using namespace pbdbench;
using namespace pbdbench::slurm;

namespace {
std::string error_of(const std::vector<std::string>& options, const fs::path& templ = {}) {
  try {
    site_settings(options, templ);
  } catch (const config::ConfigError& e) {
    return e.what();
  }
  return "";
}

Jobs example() {
  Jobs j;
  j.command = "paper";
  j.dir = "/shared/results/paper/quick/runs/slurm";
  j.workdir = "/home/me/work dir";
  j.executable = "/opt/pbdbench/bin/pbdbench";
  j.args = {"paper", "--tier", "quick", "--out", "my report", "--experiments", "exp"};
  j.shards = 4;
  j.environment = {{"PBDBENCH_DATA_DIR", "/opt/pbdbench/share/pbdbench"}};
  return j;
}
}  // namespace

TEST(Slurm, SiteOptionsAndTemplate) {
  const fs::path t = fs::temp_directory_path() / "pbdbench_test_slurm_template.sh";
  std::ofstream(t) << "#!/bin/bash\n# our site\n#SBATCH --account=proj42   # billing\n#SBATCH -p long\n\n"
                      "module load hdf5/1.10\nexport OMP_NUM_THREADS=1\n";
  const SiteSettings s = site_settings({"--time=02:00:00 -p short", "--mem=4G"}, t);
  EXPECT_EQ(s.directives,
            (std::vector<std::string>{"--account=proj42", "-p long", "--time=02:00:00", "-p short", "--mem=4G"}));
  EXPECT_EQ(s.setup, (std::vector<std::string>{"module load hdf5/1.10", "export OMP_NUM_THREADS=1"}));
  EXPECT_NE(error_of({"partition=short"}).find("not an sbatch option"), std::string::npos);
  EXPECT_NE(error_of({"--array=0-3"}).find("set by pbdbench itself"), std::string::npos);
  EXPECT_NE(error_of({"-o out.log"}).find("set by pbdbench itself"), std::string::npos);
  EXPECT_NE(error_of({"--dependency=afterok:1"}).find("set by pbdbench itself"), std::string::npos);
  const fs::path bad = fs::temp_directory_path() / "pbdbench_test_slurm_bad.sh";
  std::ofstream(bad) << "\n#SBATCH --output=x.log\n";
  EXPECT_NE(error_of({}, bad).find("pbdbench_test_slurm_bad.sh:2"), std::string::npos) << error_of({}, bad);
  EXPECT_NE(error_of({}, "/no/such/template").find("cannot read"), std::string::npos);
}

TEST(Slurm, ArrayScriptCarriesTheCommandAndTheSite) {
  SiteSettings site;
  site.directives = {"--time=01:00:00", "--cpus-per-task=8"};
  site.setup = {"module load hdf5"};
  const std::string s = array_script(example(), site);
  EXPECT_NE(s.find("#SBATCH --array=0-3\n"), std::string::npos) << s;
  EXPECT_NE(s.find("#SBATCH --chdir=/home/me/work dir\n"), std::string::npos);
  EXPECT_NE(s.find("#SBATCH --output=/shared/results/paper/quick/runs/slurm/paper-%A_%a.log\n"), std::string::npos);
  EXPECT_NE(s.find("#SBATCH --time=01:00:00\n"), std::string::npos);
  // The site's cores replace the default of one.
  EXPECT_NE(s.find("#SBATCH --cpus-per-task=8\n"), std::string::npos);
  EXPECT_EQ(s.find("--cpus-per-task=1"), std::string::npos);
  // Every #SBATCH line comes before the first command (sbatch reads no further).
  EXPECT_LT(s.rfind("#SBATCH"), s.find("module load hdf5"));
  EXPECT_LT(s.find("module load hdf5"), s.find("set -euo pipefail"));
  EXPECT_NE(s.find("export PBDBENCH_DATA_DIR=/opt/pbdbench/share/pbdbench\n"), std::string::npos);
  EXPECT_NE(s.find("\"$bin\" paper --tier quick --out 'my report' --experiments exp --shard \"${SLURM_ARRAY_TASK_ID}/4\"\n"),
            std::string::npos)
      << s;
  const std::string m = merge_script(example(), site);
  EXPECT_EQ(m.find("--array"), std::string::npos);
  EXPECT_NE(m.find("#SBATCH --cpus-per-task=1\n"), std::string::npos) << m;  // the merge makes no run
  EXPECT_EQ(m.find("--cpus-per-task=8"), std::string::npos);
  EXPECT_NE(m.find("#SBATCH --output=/shared/results/paper/quick/runs/slurm/paper-merge-%j.log\n"), std::string::npos);
  EXPECT_NE(m.find("\"$bin\" paper --tier quick --out 'my report' --experiments exp --merge 4\n"), std::string::npos) << m;
  // Both are valid bash.
  for (const std::string& script : {s, m}) {
    const fs::path p = fs::temp_directory_path() / "pbdbench_test_slurm_script.sh";
    std::ofstream(p) << script;
    EXPECT_EQ(std::system(("bash -n " + p.string()).c_str()), 0) << script;
  }
}

TEST(Slurm, WritesTheScriptsAndTheResubmission) {
  Jobs j = example();
  j.dir = fs::temp_directory_path() / "pbdbench_test_slurm_files" / "slurm";
  fs::remove_all(j.dir.parent_path());
  const ScriptFiles f = write_scripts(j, {}, {"/opt/pbdbench/bin/pbdbench", "paper", "--slurm", "4", "--slurm-opt",
                                              "--time=1:00:00 -p x"});
  EXPECT_TRUE(fs::exists(f.array));
  EXPECT_TRUE(fs::exists(f.merge));
  std::ifstream in(f.submit);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("cd '/home/me/work dir'\nexec /opt/pbdbench/bin/pbdbench paper --slurm 4 --slurm-opt "
                      "'--time=1:00:00 -p x'\n"),
            std::string::npos)
      << text;
  EXPECT_NE(fs::status(f.submit).permissions() & fs::perms::owner_exec, fs::perms::none);
}

TEST(Slurm, StripsOnlyTheSlurmOptions) {
  EXPECT_EQ(strip_slurm_options({"claims", "S5.4", "--slurm", "4", "--jobs", "2", "--slurm-opt", "--time=1:00:00",
                                 "--slurm-template=site.sh", "--no-submit", "--slurm=3", "--force"}),
            (std::vector<std::string>{"claims", "S5.4", "--jobs", "2", "--force"}));
}

TEST(Slurm, ShellQuoting) {
  EXPECT_EQ(shell_quote("results/a-b_c.h5"), "results/a-b_c.h5");
  EXPECT_EQ(shell_quote("a b"), "'a b'");
  EXPECT_EQ(shell_quote("it's"), "'it'\\''s'");
  EXPECT_EQ(shell_quote("$HOME"), "'$HOME'");
  EXPECT_EQ(shell_quote(""), "''");
}

TEST(Slurm, AllocatedCpusFollowSlurmCpusPerTask) {
  unsetenv("SLURM_CPUS_PER_TASK");
  const int all = allocated_cpus();
  EXPECT_GE(all, 1);
  setenv("SLURM_CPUS_PER_TASK", "1", 1);
  EXPECT_EQ(allocated_cpus(), 1);
  setenv("SLURM_CPUS_PER_TASK", "100000", 1);  // never more than the affinity allows
  EXPECT_EQ(allocated_cpus(), all);
  setenv("SLURM_CPUS_PER_TASK", "junk", 1);
  EXPECT_EQ(allocated_cpus(), all);
  unsetenv("SLURM_CPUS_PER_TASK");
}
