#pragma once
// `tirstrain study` (docs/study.md): the trials of a study processed into DIR/trials/NAME/, each one's
// outcome recorded in DIR/status/NAME.json, and the whole summarised in DIR/study.csv and DIR/aggregate/.
// A trial is done again only when the hash of its input files, its scene and the tirstrain version differs
// from its last complete run's. Executors (pipeline/study_executor.hpp) run each trial as a child process
// `tirstrain study run-trial DIR INDEX`, on this machine or as a Slurm array task, so both behave the same.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "pipeline/study_file.hpp"

namespace tirstrain::pipeline {

// The key results of one trial, read from its summary.json and result.h5; NaN where the trial's stages do
// not give them (no channels, no fit).
struct TrialResults {
  std::int64_t frames = 0;                                                  // frames processed
  double peak_contact_area_mm2 = std::numeric_limits<double>::quiet_NaN();  // contact.area_mm2_max
  double mu_dynamic = std::numeric_limits<double>::quiet_NaN();             // channels.mu_dynamic
  double U_t90_J = std::numeric_limits<double>::quiet_NaN();                // strain energy at t90, J
  double onset_s = std::numeric_limits<double>::quiet_NaN();                // slip onset (channels.events), s
  double t90_s = std::numeric_limits<double>::quiet_NaN();  // tangential force reaches 90 % of plateau, s
  double full_slip_s = std::numeric_limits<double>::quiet_NaN();  // full slip (stick ratio 0), s
  double mu_P_N = std::numeric_limits<double>::quiet_NaN();       // median fitted μP (/fit/limit_N), N
};

// DIR/status/NAME.json.
struct TrialStatus {
  std::string name;
  std::string status = "pending";  // pending (no file), queued, running, done, failed
  std::string hash;                // trial_hash() of the run that wrote the status
  std::string version;             // tirstrain version of that run
  std::string error;               // why it failed
  double wall_s = 0.0;             // processing time, s
  TrialResults results;            // done only
  long pid = 0;                    // running: the process running the trial
  std::string host;                // running: the machine it runs on
};

// Hex digest of the trial's input files (every regular file under its input folder, or the input file),
// its scene file's bytes and the tirstrain version.
std::string trial_hash(const StudyTrial& trial);

// Throws Error (naming --out) when `dir` exists and holds anything a study does not write: a study folder
// is kept between runs, so it must not be a process result or any other folder of the user's.
void check_study_folder(const std::string& dir);

// DIR/plan.json: the trials and settings the executors' tasks read (so a task runs what was planned even
// when the study file changes meanwhile).
void write_plan(const std::string& dir, const StudySpec& spec);
StudySpec read_plan(const std::string& dir);

// The status file as written (what the executors act on).
TrialStatus read_status(const std::string& dir, const std::string& name);
// The same as a user is shown it: a trial still "running" by a process that is gone from this machine (a
// killed study) is failed, "interrupted". A Slurm task is judged by its executor through sacct instead.
TrialStatus observed_status(const std::string& dir, const std::string& name);

// Indices of the trials whose last complete run does not match their current hash (or that never ran).
std::vector<std::size_t> trials_needing_work(const std::string& dir, const StudySpec& spec);

// Processes trial `index` of the plan into DIR/trials/NAME/ and records the outcome; true when done.
// A failure is recorded (status failed with the message), not thrown.
bool run_study_trial(const std::string& dir, std::size_t index);

// Records a failure that the trial's own process could not record (killed, crashed, lost by Slurm).
void record_failure(const std::string& dir, const StudyTrial& trial, const std::string& error);

// Records that the trial is submitted and waits for its task (status queued).
void mark_queued(const std::string& dir, const StudyTrial& trial);

// Hex digest of plan.json and study.csv (the trials' outcomes and key results, not their timings):
// aggregate/ is rebuilt only when it changes.
std::string study_fingerprint(const std::string& dir);

// DIR/study.csv from the plan and the status files.
void write_study_csv(const std::string& dir, const StudySpec& spec);

// One line per status with counts, and the failed trials with their errors.
std::string study_status_text(const std::string& dir, const StudySpec& spec);

// DIR/aggregate/ (power laws, averaged maps, per-condition table), built by running `cli` (this binary)
// for `signals power-law` and `average`, staged and swapped in whole. Returns the problems met (a power law
// with too few trials, say); they are also recorded in aggregate/aggregate.json. Needs DIR/study.csv;
// an aggregate/ built from the same plan and study.csv is kept as it is.
std::vector<std::string> aggregate_study(const std::string& dir, const StudySpec& spec,
                                         const std::string& cli);

}  // namespace tirstrain::pipeline
