#pragma once
// The study file (YAML, docs/study.md): the trials of a study with their conditions, what to aggregate
// across them, and the Slurm resources of one trial. Validated as strictly as scene files: every key is
// known and typed, and errors name the file, the key path and the line.
#include <map>
#include <string>
#include <vector>

namespace tirstrain::pipeline {

struct StudyTrial {
  std::string name;                               // unique; the folder DIR/trials/NAME
  std::string input;                              // recording, absolute (relative to the study file)
  std::string scene;                              // scene file, absolute; empty: process's own rule
  std::map<std::string, std::string> conditions;  // condition key -> value, as written
};

// One fit of mu = a * W^b across the trials (tirstrain signals power-law).
struct StudyPowerLaw {
  std::string name;                 // output stem: aggregate/power_law_NAME.{csv,json}
  std::string normal = "normal_N";  // study.csv column (condition or result) giving W, N
  std::string mu = "mu_dynamic";    // study.csv column giving mu
};

struct StudyAggregate {
  std::vector<StudyPowerLaw> power_laws;
  // Condition keys whose value combinations group the trials for the averaged strain maps
  // (aggregate/maps/KEY=VALUE,.../); empty: no maps.
  std::vector<std::string> maps_by;
  // Condition keys grouping aggregate/conditions.csv; empty: every condition key of the study.
  std::vector<std::string> table_by;
};

// Resources of one Slurm array task (sbatch options); empty or 0: the cluster's default.
struct StudySlurm {
  std::string partition;   // --partition
  long cpus_per_task = 1;  // --cpus-per-task
  long mem_MB = 0;         // --mem, MB; 0: cluster default
  long time_min = 0;       // --time, minutes; 0: cluster default
};

struct StudySpec {
  std::string file;                  // the study file, absolute
  std::vector<StudyTrial> trials;    // in file order (glob form: sorted by path)
  std::vector<std::string> compute;  // stages added to each trial's scene list (process --compute)
  StudyAggregate aggregate;
  StudySlurm slurm;
};

// Reads and validates a study file; throws Error naming the file, key and line of the first problem.
StudySpec load_study_file(const std::string& path);

}  // namespace tirstrain::pipeline
