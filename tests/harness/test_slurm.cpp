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
  EXPECT_NE(error_of({"--array=0-3"}).find("which pbdbench sets itself"), std::string::npos);
  EXPECT_NE(error_of({"-o out.log"}).find("which pbdbench sets itself"), std::string::npos);
  EXPECT_NE(error_of({"--dependency=afterok:1"}).find("which pbdbench sets itself"), std::string::npos);
  // Every spelling sbatch accepts of the options pbdbench sets: an unambiguous prefix of a long
  // option (getopt_long), a short option alone, with its value attached or in a group of flags.
  for (const std::string& o :
       {"--out=/x", "--outp=/x", "--dep=afterok:1", "--depend=afterok:1", "--ar=0-9", "--arr", "--err=/x",
        "--ch=/", "--chd=/tmp", "--work=/", "--workdir=/", "--pars", "--wr=touch x", "--wrap=touch x",
        "-o/x", "-o /x", "-e /x", "-a 1", "-a1", "-d afterok:1", "-D /", "-D/", "-P afterok:1", "-Ho/x",
        "-vHd afterok:1", "-Qa 0-9", "-vD /"})
    EXPECT_NE(error_of({o}).find("which pbdbench sets itself"), std::string::npos) << o << ": " << error_of({o});
  EXPECT_NE(error_of({"--out=/x"}).find("'--out=/x' is --output to sbatch"), std::string::npos) << error_of({"--out=/x"});
  EXPECT_NE(error_of({"-Ho/x"}).find("is -o (--output) to sbatch"), std::string::npos) << error_of({"-Ho/x"});
  // What sbatch reads as other options stays allowed: a flag group ending in an option with a
  // value, where a later letter is part of the value ("-pdebug" is the partition "debug").
  for (const std::string& o : {"--partition=short", "--part=short", "-p short", "-pdebug", "-Hp short", "--time=1:00:00",
                               "--comment=--output=x", "--job-name=a", "--export=NONE", "--account=ops", "-A ops"})
    EXPECT_EQ(error_of({o}), "") << o;
  // Not options at all, or an option that ends sbatch's options.
  for (const std::string& o : {"-", "--"}) EXPECT_NE(error_of({o}).find("not an sbatch option"), std::string::npos) << o;
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
  // sbatch splits an #SBATCH line at blanks: a folder with one is quoted for it.
  EXPECT_NE(s.find("#SBATCH --chdir=\"/home/me/work dir\"\n"), std::string::npos) << s;
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

TEST(Slurm, SiteCoresInAnySpelling) {
  // The merge takes one core whatever spelling the site gave --cpus-per-task in.
  for (const std::string& cores : {"--cpus-per-task=8", "--cpus-per=8", "-c 8", "-c8", "-Hc 8"}) {
    SiteSettings site;
    site.directives = {cores};
    const std::string a = array_script(example(), site);
    EXPECT_EQ(a.find("--cpus-per-task=1"), std::string::npos) << cores << "\n" << a;
    const std::string m = merge_script(example(), site);
    EXPECT_NE(m.find("#SBATCH --cpus-per-task=1\n"), std::string::npos) << cores;
    EXPECT_EQ(m.find(cores), std::string::npos) << cores << "\n" << m;
  }
}

TEST(Slurm, RefusesControlCharactersInAnyValue) {
  auto refusal = [](const Jobs& j) -> std::string {
    try {
      array_script(j, {});
    } catch (const config::ConfigError& e) {
      return e.what();
    }
    return "";
  };
  for (const std::string& bad : {std::string("x\ntouch /tmp/pbdbench_canary\n#"), std::string("a\rb"),
                                 std::string("tab\there"), std::string("bell\x07"), std::string("del\x7f")}) {
    Jobs j = example();
    j.dir = "/shared/" + bad + "/slurm";
    EXPECT_NE(refusal(j).find("the folder of the run files and the Slurm logs"), std::string::npos) << refusal(j);
    EXPECT_NE(refusal(j).find("nothing was written"), std::string::npos);
    j = example();
    j.workdir = "/home/" + bad;
    EXPECT_NE(refusal(j).find("the working folder"), std::string::npos) << refusal(j);
    j = example();
    j.args.push_back(bad);
    EXPECT_NE(refusal(j).find("argument 8 of the command line"), std::string::npos) << refusal(j);
    j = example();
    j.environment = {{"PBDBENCH_DATA_DIR", bad}};
    EXPECT_NE(refusal(j).find("$PBDBENCH_DATA_DIR"), std::string::npos) << refusal(j);
    j = example();
    j.executable = "/opt/" + bad;
    EXPECT_NE(refusal(j).find("executable"), std::string::npos) << refusal(j);
    EXPECT_NE(error_of({"--comment=" + bad}), "") << bad;  // split at a blank, or refused for its control character
  }
  EXPECT_NE(error_of({"--comment=a\x07" "b"}).find("the control character \\x07"), std::string::npos)
      << error_of({"--comment=a\x07" "b"});
  Jobs j = example();
  j.dir = "/shared/x\ntouch y/slurm";
  EXPECT_NE(refusal(j).find("'/shared/x\\ntouch y/slurm' holds a newline (at byte 9)"), std::string::npos) << refusal(j);
}

TEST(Slurm, SbatchQuoting) {
  EXPECT_EQ(sbatch_quote("/shared/results/a-b_c"), "/shared/results/a-b_c");
  EXPECT_EQ(sbatch_quote("a b"), "\"a b\"");
  EXPECT_EQ(sbatch_quote("a\"b\\c'#d"), "\"a\\\"b\\\\c'#d\"");
  // The logs' folder: a '%' of its name doubled, since --output reads %A, %a, %j.
  Jobs j = example();
  j.dir = "/shared/100% sure/slurm";
  const std::string s = array_script(j, {});
  EXPECT_NE(s.find("#SBATCH --output=\"/shared/100%% sure/slurm/paper-%A_%a.log\"\n"), std::string::npos) << s;
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
