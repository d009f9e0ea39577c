// `tirstrain study`: many trials processed resumably, here or on a Slurm cluster, then aggregated
// (docs/study.md).
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "core/atomic_output.hpp"
#include "core/error.hpp"
#include "pipeline/study.hpp"
#include "pipeline/study_executor.hpp"
#include "tirstrain/camera_options.hpp"
#include "tirstrain/commands.hpp"
#include "tirstrain/value_checks.hpp"

namespace tirstrain::cli {
namespace {

namespace fs = std::filesystem;
namespace pl = tirstrain::pipeline;

// This binary, which each trial's child process and Slurm task runs.
std::string self_path() {
  std::vector<char> buffer(4096);
  const ssize_t n = ::readlink("/proc/self/exe", buffer.data(), buffer.size() - 1);
  if (n <= 0) throw Error("cannot find this program's path (/proc/self/exe)");
  return std::string(buffer.data(), static_cast<std::size_t>(n));
}

// study.csv and aggregate/ from the status files; warnings for what could not be aggregated.
void summarise(const std::string& dir, const pl::StudySpec& spec, bool quiet) {
  pl::write_study_csv(dir, spec);
  for (const std::string& p : pl::aggregate_study(dir, spec, self_path()))
    std::cerr << "tirstrain: warning: aggregate: " << p << "\n";
  if (!quiet) std::cerr << pl::study_status_text(dir, spec);
}

int failed_trials(const std::string& dir, const pl::StudySpec& spec) {
  int n = 0;
  for (const pl::StudyTrial& t : spec.trials) n += pl::observed_status(dir, t.name).status != "done";
  return n;
}

void add_run(CLI::App& study) {
  struct Args {
    std::string file, out, executor = "local";
    int jobs = 1;
    bool no_wait = false, quiet = false;
    double poll_s = 5.0;
  };
  auto a = std::make_shared<Args>();
  CLI::App* sub =
      study.add_subcommand("run", "Process every trial that changed, then write study.csv and aggregate/");
  sub->add_option("STUDY", a->file, "Study file (YAML, docs/study.md)")->required()->check(CLI::ExistingFile);
  sub->add_option("--out", a->out, "Study folder (created; kept between runs: unchanged trials are skipped)")
      ->required();
  sub->add_option("--jobs", a->jobs, "Trials processed at the same time by the local executor (default 1)")
      ->check(CLI::Range(1, 256));
  sub->add_option("--executor", a->executor, "local (default) or slurm (a job array through sbatch)")
      ->check(CLI::IsMember({"local", "slurm"}));
  sub->add_flag("--no-wait", a->no_wait,
                "slurm: submit and return; 'study status' and 'study aggregate' follow");
  sub->add_option("--poll-s", a->poll_s, "slurm: seconds between squeue polls (default 5)")->check(kPositive);
  sub->add_flag("--quiet", a->quiet, "No progress bar or summary on stderr");
  sub->callback([a] {
    const pl::StudySpec spec = pl::load_study_file(a->file);
    for (const pl::StudyTrial& t : spec.trials)
      if (path_is_within(a->out, t.input))
        throw Error("the study folder must not lie inside a trial's input (" + t.name + ")",
                    {.key = "--out"});
    pl::check_study_folder(a->out);
    fs::create_directories(a->out);
    const std::string dir = fs::absolute(a->out).lexically_normal().string();
    pl::write_plan(dir, spec);
    const std::vector<std::size_t> work = pl::trials_needing_work(dir, spec);
    if (!a->quiet)
      std::cerr << work.size() << " of " << spec.trials.size() << " trials to process ("
                << spec.trials.size() - work.size() << " unchanged since their last complete run)\n";
    if (!work.empty() && a->executor == "slurm") {
      pl::SlurmExecutorOptions o{self_path(), !a->no_wait, a->poll_s, a->quiet};
      pl::run_slurm(dir, spec, work, o);
      if (a->no_wait) return;
    } else if (!work.empty()) {
      install_interrupt_handler();
      pl::run_local(dir, spec, work, {self_path(), a->jobs, a->quiet, &interrupt_flag()});
    }
    summarise(dir, spec, a->quiet);
    if (const int failed = failed_trials(dir, spec); failed > 0)
      throw Error(std::to_string(failed) + " trial(s) not done (study.csv, status/ and logs/ say why)",
                  {.file = dir});
  });
}

void add_run_trial(CLI::App& study) {
  struct Args {
    std::string dir;
    std::size_t index = 0;
  };
  auto a = std::make_shared<Args>();
  CLI::App* sub = study.add_subcommand(
      "run-trial", "Process one trial of a planned study (what each executor's task runs)");
  sub->add_option("DIR", a->dir, "Study folder (holding plan.json)")->required();
  sub->add_option("INDEX", a->index, "0-based trial index in plan.json")
      ->required()
      ->check(kWholeAtLeastZero);
  sub->callback([a] {
    if (!pl::run_study_trial(a->dir, a->index)) {
      const pl::StudySpec spec = pl::read_plan(a->dir);
      throw Error("trial " + spec.trials[a->index].name +
                  " failed: " + pl::read_status(a->dir, spec.trials[a->index].name).error);
    }
  });
}

void add_status(CLI::App& study) {
  auto dir = std::make_shared<std::string>();
  CLI::App* sub =
      study.add_subcommand("status", "Summarise a study folder: trials done, failed, running, queued");
  sub->add_option("DIR", *dir, "Study folder")->required();
  sub->callback([dir] { std::cout << pl::study_status_text(*dir, pl::read_plan(*dir)); });
}

void add_aggregate(CLI::App& study) {
  auto dir = std::make_shared<std::string>();
  CLI::App* sub = study.add_subcommand(
      "aggregate", "Write study.csv and aggregate/ from the trials done so far (after --no-wait)");
  sub->add_option("DIR", *dir, "Study folder")->required();
  sub->callback([dir] {
    const std::string abs = fs::absolute(*dir).lexically_normal().string();
    summarise(abs, pl::read_plan(abs), false);
  });
}

}  // namespace

void add_study_command(CLI::App& app) {
  CLI::App* study =
      app.add_subcommand("study", "Run many trials resumably (here or on Slurm) and aggregate them");
  study->require_subcommand(1);
  study->footer(
      "Example:\n"
      "  tirstrain study run study.yaml --out results/ --jobs 2\n"
      "  tirstrain study run study.yaml --out results/ --executor slurm --no-wait\n"
      "  tirstrain study status results/ && tirstrain study aggregate results/\n"
      "study.yaml lists the trials ({name, input, scene, conditions}) or a glob (inputs: \"rec/*/\") and "
      "what to\n"
      "aggregate (docs/study.md). Each trial goes to DIR/trials/NAME/ (tirstrain process; no overlay) and "
      "is\n"
      "skipped when its input files, scene and the tirstrain version hash as at its last complete run.\n"
      "DIR/study.csv has one row per trial; DIR/aggregate/ the power laws, averaged maps and "
      "conditions.csv.");
  add_run(*study);
  add_run_trial(*study);
  add_status(*study);
  add_aggregate(*study);
}

}  // namespace tirstrain::cli
