#include "pipeline/study_executor.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "core/atomic_output.hpp"
#include "core/error.hpp"

extern char** environ;

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// A trial's child process. With several trials at a time each gets its share of the cores for its image
// loops (`tirstrain --threads`): trials side by side use the cores better than one trial's parallel loops
// over a few hundred tracks, whose threads would otherwise compete with the other trials' for the same cores.
std::vector<std::string> trial_command(const std::string& cli, const std::string& dir, std::size_t index,
                                       int jobs) {
  std::vector<std::string> argv{cli};
  if (jobs > 1) {
    const long cores = std::max(1L, ::sysconf(_SC_NPROCESSORS_ONLN));
    argv.insert(argv.end(), {"--threads", std::to_string(std::max(1L, cores / jobs))});
  }
  argv.insert(argv.end(), {"study", "run-trial", dir, std::to_string(index)});
  return argv;
}

pid_t spawn(const std::vector<std::string>& argv, const std::string& log) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!log.empty()) {
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
  }
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw Error("cannot start " + argv[0] + ": " + std::strerror(rc));
  return pid;
}

int exit_code(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return WIFSIGNALED(status) ? 128 + WTERMSIG(status) : 1;
}

std::string duration_text(double s) {
  const long t = std::lround(s);
  if (t >= 3600) return std::to_string(t / 3600) + "h" + std::to_string((t % 3600) / 60) + "m";
  if (t >= 60) return std::to_string(t / 60) + "m" + std::to_string(t % 60) + "s";
  return std::to_string(t) + "s";
}

// "study [#####-----] 3/8 trials (1 failed), 2 running, ~1m20s left": the time left assumes the trials
// still to finish take as long on average as those finished, `parallel` at a time.
class StudyProgress {
 public:
  StudyProgress(std::size_t total, bool quiet) : total_(total), quiet_(quiet), tty_(isatty(2) != 0) {}
  void draw(std::size_t finished, std::size_t failed, std::size_t running) {
    if (quiet_) return;
    const double elapsed_s = std::chrono::duration<double>(Clock::now() - start_).count();
    constexpr int kWidth = 24;
    const int filled = total_ == 0 ? kWidth : static_cast<int>(kWidth * finished / total_);
    std::ostringstream line;
    line << "study [" << std::string(filled, '#') << std::string(kWidth - filled, '-') << "] " << finished
         << "/" << total_ << " trials";
    if (failed > 0) line << " (" << failed << " failed)";
    line << ", " << running << " running";
    if (finished > 0 && finished < total_)
      line << ", ~"
           << duration_text(elapsed_s / static_cast<double>(finished) *
                            static_cast<double>(total_ - finished))
           << " left";
    if (finished == total_) line << ", " << duration_text(elapsed_s);
    std::fprintf(stderr, tty_ ? "\r%-78s" : "%s\n", line.str().c_str());
    if (tty_ && finished == total_) std::fputc('\n', stderr);
    std::fflush(stderr);
  }

 private:
  std::size_t total_;
  bool quiet_, tty_;
  Clock::time_point start_ = Clock::now();
};

std::string log_path(const std::string& dir, const std::string& name) {
  return (fs::path(dir) / "logs" / (name + ".log")).string();
}

// A child that ended without recording its outcome (crashed, killed) is recorded as failed here.
void check_recorded(const std::string& dir, const StudyTrial& trial, int code) {
  const TrialStatus s = read_status(dir, trial.name);
  if (s.status == "done" || s.status == "failed") return;
  record_failure(dir, trial,
                 "the trial's process ended with exit code " + std::to_string(code) +
                     " before recording its outcome (see logs/" + trial.name + ".log)");
}

// Where each array task writes "ARRAY_JOB_ID TASK_JOB_ID" as it starts (file named by the trial index).
fs::path task_ids_dir(const std::string& dir) {
  return fs::path(dir) / "slurm" / "tasks";
}

std::string slurm_script(const std::string& dir, const StudySpec& spec,
                         const std::vector<std::size_t>& indices, const std::string& cli) {
  const StudySlurm& r = spec.slurm;
  std::string array;
  for (std::size_t i : indices) array += (array.empty() ? "" : ",") + std::to_string(i);
  std::ostringstream s;
  s << "#!/bin/sh\n# Written by tirstrain study run --executor slurm: one array task per trial.\n"
    << "#SBATCH --job-name=tirstrain-study\n#SBATCH --array=" << array << "\n"
    << "#SBATCH --cpus-per-task=" << r.cpus_per_task << "\n"
    << "#SBATCH --output=" << (fs::path(dir) / "logs" / "slurm-%A_%a.log").string() << "\n";
  if (!r.partition.empty()) s << "#SBATCH --partition=" << r.partition << "\n";
  if (r.mem_MB > 0) s << "#SBATCH --mem=" << r.mem_MB << "M\n";
  if (r.time_min > 0) s << "#SBATCH --time=" << r.time_min << "\n";
  // Each task's own job id, for sacct --completion, which names tasks by it alone.
  s << "echo \"$SLURM_ARRAY_JOB_ID $SLURM_JOB_ID\" > '" << task_ids_dir(dir).string()
    << "'/\"$SLURM_ARRAY_TASK_ID\"\n";
  // The task's image loops use the CPUs Slurm gave it (every core of the node otherwise).
  s << "exec '" << cli << "' --threads \"${SLURM_CPUS_PER_TASK:-0}\" study run-trial '" << dir
    << "' \"$SLURM_ARRAY_TASK_ID\"\n";
  return s.str();
}

std::size_t count_recorded(const std::string& dir, const StudySpec& spec,
                           const std::vector<std::size_t>& indices, std::size_t* failed) {
  std::size_t n = 0;
  *failed = 0;
  for (std::size_t i : indices) {
    const std::string s = read_status(dir, spec.trials[i].name).status;
    n += s == "done" || s == "failed";
    *failed += s == "failed";
  }
  return n;
}

// True while the job has tasks pending or running. squeue forgets a finished job after MinJobAge and then
// says "Invalid job id": that is the job's end too, not an error.
bool job_queued(const std::string& job) {
  try {
    return !run_command("squeue -h -j " + job + " -o %i").empty();
  } catch (const Error& e) {
    if (std::string(e.what()).find("Invalid job id") != std::string::npos) return false;
    throw;
  }
}

struct TaskEnd {
  std::string state;      // Slurm's job state (TIMEOUT, CANCELLED, …)
  std::string exit_code;  // "exit:signal"
};

// sacct -P rows "ID|STATE|EXIT" as id -> end; other lines (sacct's warnings, which run_command merges into
// its output) are skipped.
std::map<std::string, TaskEnd> sacct_rows(const std::string& out) {
  std::map<std::string, TaskEnd> rows;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    const std::size_t a = line.find('|'), b = line.find('|', a + 1);
    if (a == std::string::npos || b == std::string::npos || line.find('|', b + 1) != std::string::npos)
      continue;
    std::string state = line.substr(a + 1, b - a - 1);
    state = state.substr(0, state.find(' '));  // "CANCELLED by 0" -> CANCELLED
    rows[line.substr(0, a)] = {state, line.substr(b + 1)};
  }
  return rows;
}

// Why sacct failed: the last non-empty line it printed (run_command's message is "'COMMAND' failed (exit
// N): OUTPUT"), or the whole message when it printed nothing.
std::string sacct_reason(const Error& e) {
  const std::string text = e.what();
  const std::size_t output = text.find("): ");
  std::istringstream lines(output == std::string::npos ? text : text.substr(output + 3));
  std::string last;
  for (std::string line; std::getline(lines, line);)
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  return last.empty() ? text : last;
}

// How the tasks `indices` of `job` ended, by trial index, from sacct. With accounting storage (slurmdbd)
// sacct names array tasks JOB_INDEX; without it, a cluster that logs job completions (JobCompType, e.g.
// jobcomp/filetxt) still answers sacct --completion, which names each task by its own job id only, so the
// ids the tasks wrote as they started map them back. Tasks that never started, or that sacct does not know,
// are absent. Sets `why` when neither form answers.
std::map<std::size_t, TaskEnd> task_ends(const std::string& dir, const std::string& job,
                                         const std::vector<std::size_t>& indices, std::string* why) {
  std::map<std::size_t, TaskEnd> ends;
  const std::string format = " -n -P -X --format=JobID,State,ExitCode";
  try {
    for (const auto& [id, end] : sacct_rows(run_command("sacct -j " + job + format)))
      for (std::size_t i : indices)
        if (id == job + "_" + std::to_string(i)) ends[i] = end;
    return ends;
  } catch (const Error& e) {
    *why = "sacct: " + sacct_reason(e);
  }
  std::map<std::string, std::size_t> index_of;  // task's own job id -> trial index
  std::string ids;
  for (std::size_t i : indices) {
    std::ifstream in(task_ids_dir(dir) / std::to_string(i));
    std::string array_job, task_job;
    if (in >> array_job >> task_job && array_job == job) {
      index_of[task_job] = i;
      ids += (ids.empty() ? "" : ",") + task_job;
    }
  }
  if (ids.empty()) {
    *why += "; sacct --completion: no job id to ask about (none of these tasks started)";
    return ends;
  }
  try {
    for (const auto& [id, end] : sacct_rows(run_command("sacct --completion -j " + ids + format)))
      if (index_of.count(id)) ends[index_of.at(id)] = end;
    why->clear();
  } catch (const Error& e) {
    *why += "; sacct --completion: " + sacct_reason(e);
  }
  return ends;
}

// A task's final Slurm state for the trial's error: "CANCELLED (cancelled by scancel or by the cluster;
// exit code:signal 0:15)".
std::string state_meaning(const TaskEnd& end) {
  const std::string& s = end.state;
  const std::string code = "exit code:signal " + end.exit_code;
  if (s == "TIMEOUT") return s + " (its time limit reached: the study file's slurm: time_min; " + code + ")";
  if (s == "OUT_OF_MEMORY") return s + " (out of memory: the study file's slurm: mem_MB; " + code + ")";
  if (s == "CANCELLED") return s + " (cancelled by scancel or by the cluster; " + code + ")";
  if (s == "NODE_FAIL") return s + " (its node failed; " + code + ")";
  if (s == "FAILED") return s + " (its process exited non-zero or was killed; " + code + ")";
  return s + " (" + code + ")";
}

// The Slurm states in which a task has ended; sacct may still say RUNNING or COMPLETING for a moment after
// the job has left squeue, and such a state says nothing about how the task ended.
bool final_state(const std::string& s) {
  for (const char* f : {"BOOT_FAIL", "CANCELLED", "COMPLETED", "DEADLINE", "FAILED", "NODE_FAIL",
                        "OUT_OF_MEMORY", "PREEMPTED", "TIMEOUT"})
    if (s == f) return true;
  return false;
}

}  // namespace

int run_child(const std::vector<std::string>& argv, const std::string& log) {
  const pid_t pid = spawn(argv, log);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) throw Error(std::string("waiting for ") + argv[0] + ": " + std::strerror(errno));
  return exit_code(status);
}

std::string run_command(const std::string& command) {
  std::FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) throw Error("cannot run: " + command);
  std::string out;
  char buffer[4096];
  while (const std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) out.append(buffer, n);
  const int status = ::pclose(pipe);
  if (status != 0)
    throw Error("'" + command + "' failed (exit " + std::to_string(exit_code(status)) + "): " + out);
  return out;
}

// The study run was asked to stop: its running trials end with it rather than run on unwatched (a later
// run would find them still writing), and each is recorded as interrupted.
[[noreturn]] void stop_running_trials(const std::string& dir, const StudySpec& spec,
                                      const std::map<pid_t, std::size_t>& running) {
  for (const auto& [pid, index] : running) ::kill(pid, SIGTERM);
  for (const auto& [pid, index] : running) {
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    const TrialStatus s = read_status(dir, spec.trials[index].name);
    if (s.status != "done" && s.status != "failed")
      record_failure(dir, spec.trials[index], "interrupted: the study run was stopped while this trial ran");
  }
  throw Error("interrupted: " + std::to_string(running.size()) +
                  " running trial(s) stopped; run the study again to finish them",
              {.file = dir});
}

int run_local(const std::string& dir, const StudySpec& spec, const std::vector<std::size_t>& indices,
              const LocalExecutorOptions& options) {
  fs::create_directories(fs::path(dir) / "logs");
  StudyProgress progress(indices.size(), options.quiet);
  std::map<pid_t, std::size_t> running;  // child -> trial index
  std::size_t next = 0, finished = 0, failed = 0;
  progress.draw(0, 0, 0);
  while (finished < indices.size()) {
    while (next < indices.size() && running.size() < static_cast<std::size_t>(std::max(1, options.jobs))) {
      const std::size_t i = indices[next++];
      std::remove(log_path(dir, spec.trials[i].name).c_str());
      running[spawn(trial_command(options.cli, dir, i, options.jobs), log_path(dir, spec.trials[i].name))] =
          i;
    }
    int status = 0;
    const pid_t pid = waitpid(-1, &status, 0);
    if (pid < 0) {
      if (errno == EINTR && options.stop && options.stop->load()) stop_running_trials(dir, spec, running);
      if (errno == EINTR) continue;
      throw Error(std::string("waiting for the trials: ") + std::strerror(errno));
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    const int code = exit_code(status);
    check_recorded(dir, spec.trials[it->second], code);
    failed += code != 0;
    running.erase(it);
    progress.draw(++finished, failed, running.size());
    if (options.stop && options.stop->load()) stop_running_trials(dir, spec, running);
  }
  return static_cast<int>(failed);
}

std::string run_slurm(const std::string& dir, const StudySpec& spec, const std::vector<std::size_t>& indices,
                      const SlurmExecutorOptions& options) {
  fs::create_directories(fs::path(dir) / "logs");
  fs::create_directories(fs::path(dir) / "slurm");
  const std::string script = (fs::path(dir) / "slurm" / "job.sh").string();
  // An earlier outcome must not count as this job's: each submitted trial waits as "queued".
  for (std::size_t i : indices) mark_queued(dir, spec.trials[i]);
  fs::remove_all(task_ids_dir(dir));  // an earlier job's task ids would name other tasks
  fs::create_directories(task_ids_dir(dir));
  write_text_file(script, slurm_script(dir, spec, indices, options.cli));
  std::string job;
  try {
    job = run_command("sbatch --parsable '" + script + "'");
    job = job.substr(0, job.find_first_of(";\n"));
    if (job.empty()) throw Error("sbatch printed no job id", {.file = script});
  } catch (const Error& e) {
    // Nothing was submitted: no trial may wait as "queued" for a job that does not exist.
    for (std::size_t i : indices) record_failure(dir, spec.trials[i], "not submitted: " + e.message());
    throw;
  }
  write_text_file((fs::path(dir) / "slurm" / "job_id").string(), job + "\n");
  if (!options.quiet)
    std::fprintf(stderr, "submitted Slurm job %s (%zu tasks)\n", job.c_str(), indices.size());
  if (!options.wait) return job;
  StudyProgress progress(indices.size(), options.quiet);
  std::size_t failed = 0, last = static_cast<std::size_t>(-1);
  for (;;) {
    const bool queued = job_queued(job);
    const std::size_t done = count_recorded(dir, spec, indices, &failed);
    if (done != last || !queued) progress.draw(done, failed, queued ? indices.size() - done : 0);
    last = done;
    if (!queued) break;
    std::this_thread::sleep_for(std::chrono::duration<double>(options.poll_s));
  }
  // sacct is asked only about tasks that recorded no outcome: a trial's own record says more than its
  // task's Slurm state.
  std::vector<std::size_t> silent;
  for (std::size_t i : indices) {
    const std::string s = read_status(dir, spec.trials[i].name).status;
    if (s != "done" && s != "failed") silent.push_back(i);
  }
  if (silent.empty()) return job;
  std::string why;
  const std::map<std::size_t, TaskEnd> ends = task_ends(dir, job, silent, &why);
  if (!why.empty())
    std::fprintf(stderr,
                 "tirstrain: sacct cannot say how Slurm job %s's tasks ended (%s); the tasks that recorded "
                 "no outcome are recorded as failed without their Slurm state\n",
                 job.c_str(), why.c_str());
  for (std::size_t i : silent) {
    const auto end = ends.find(i);
    const std::string state = end != ends.end() && final_state(end->second.state)
                                  ? " in Slurm state " + state_meaning(end->second)
                                  : "";
    record_failure(dir, spec.trials[i],
                   "Slurm job " + job + " task " + std::to_string(i) + " ended" + state +
                       " without recording its outcome (see logs/slurm-" + job + "_" + std::to_string(i) +
                       ".log)");
  }
  return job;
}

}  // namespace tirstrain::pipeline
