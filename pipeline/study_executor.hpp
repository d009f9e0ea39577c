#pragma once
// Executors of `tirstrain study run`: each trial needing work is one child process
// `CLI study run-trial DIR INDEX` (CLI: this binary), either run here, `jobs` at a time, or submitted as one
// task of a Slurm job array (sbatch), waited for (squeue) and asked how it ended (sacct). No scheduling of
// our own beyond that.
#include <atomic>
#include <string>
#include <vector>

#include "pipeline/study.hpp"

namespace tirstrain::pipeline {

struct LocalExecutorOptions {
  std::string cli;     // path of the tirstrain binary that runs each trial
  int jobs = 1;        // trials processed at the same time
  bool quiet = false;  // no progress bar on stderr
  // Set by a SIGINT/SIGTERM handler: the running trials are stopped (SIGTERM), waited for and recorded as
  // interrupted, and run_local throws; nullptr: not watched.
  const std::atomic<bool>* stop = nullptr;
};

// Runs the trials `indices` of the plan in DIR; returns how many failed. Each child's output goes to
// DIR/logs/NAME.log.
int run_local(const std::string& dir, const StudySpec& spec, const std::vector<std::size_t>& indices,
              const LocalExecutorOptions& options);

struct SlurmExecutorOptions {
  std::string cli;      // path of the tirstrain binary, reachable from the compute nodes
  bool wait = true;     // false: submit and return (tirstrain study status DIR follows the job)
  double poll_s = 5.0;  // interval between squeue polls, s
  bool quiet = false;   // no progress bar on stderr
};

// Writes DIR/slurm/job.sh, submits it as an array over `indices` with the study's resources, and (wait)
// polls squeue until the job has left the queue. Tasks that ended without recording a status are recorded
// as failed, with the Slurm state sacct gives for them (TIMEOUT, OUT_OF_MEMORY, CANCELLED, …) when it
// answers; when it does not, one line on stderr says why. Returns the Slurm job id.
std::string run_slurm(const std::string& dir, const StudySpec& spec, const std::vector<std::size_t>& indices,
                      const SlurmExecutorOptions& options);

// Runs argv[0] with argv, its stdout and stderr appended to `log` (empty: inherited); returns its exit
// code, or 128 + N when killed by signal N.
int run_child(const std::vector<std::string>& argv, const std::string& log);

// Runs a shell command and returns its stdout; throws Error with the output when it exits non-zero.
std::string run_command(const std::string& command);

}  // namespace tirstrain::pipeline
