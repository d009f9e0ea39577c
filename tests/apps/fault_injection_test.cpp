// Faults injected into the real CLI: SIGKILL at random points of process, synth and record; a full disk at
// several sizes; a read-only output folder; outputs that are or hold their inputs. Each case asserts the
// exit code, a message naming the cause, the earlier complete result left byte for byte, and nothing that
// looks complete left behind.
//
// "Disk full" is the file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored: writes past it fail with EFBIG, "File
// too large"), which an unprivileged test can set on the child; a real full filesystem (ENOSPC) takes the
// same code paths. "Read-only" is a read-only bind mount when the test runs as root (root ignores mode
// bits) and mode 0555 otherwise.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/h5_file.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int exit_code = -1;    // exit status, or 128 + signal
  bool killed = false;   // ended by the SIGKILL the test sent
  std::string output;    // stdout and stderr
  double seconds = 0.0;  // wall time
};

struct RunOptions {
  std::optional<rlim_t> file_size_limit_bytes;  // RLIMIT_FSIZE of the child
  std::optional<double> kill_after_s;           // SIGKILL this long after the start
  std::optional<fs::path> kill_once_exists;     // SIGKILL as soon as this file exists (polled every 5 ms)
};

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Runs the tirstrain binary with `args`, collecting its output; limits and kills it as `options` asks.
CliRun run_cli(const std::vector<std::string>& args, const RunOptions& options = {}) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const double start_s = now_s();
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(fds[1], STDOUT_FILENO);
    dup2(fds[1], STDERR_FILENO);
    close(fds[0]);
    close(fds[1]);
    signal(SIGXFSZ, SIG_IGN);
    if (options.file_size_limit_bytes) {
      const rlimit limit{*options.file_size_limit_bytes, *options.file_size_limit_bytes};
      setrlimit(RLIMIT_FSIZE, &limit);
    }
    std::vector<char*> argv{const_cast<char*>(TIRSTRAIN_CLI)};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(TIRSTRAIN_CLI, argv.data());
    _exit(127);
  }
  close(fds[1]);
  CliRun run;
  bool sent_kill = false;
  for (;;) {
    int timeout_ms = -1;
    if (options.kill_after_s && !sent_kill)
      timeout_ms = std::max(0, static_cast<int>(1e3 * (start_s + *options.kill_after_s - now_s())));
    if (options.kill_once_exists && !sent_kill) timeout_ms = 5;
    pollfd p{fds[0], POLLIN, 0};
    const int ready = poll(&p, 1, timeout_ms);
    if (ready == 0) {
      if (!options.kill_once_exists || fs::exists(*options.kill_once_exists)) {
        kill(pid, SIGKILL);
        sent_kill = true;
      }
      continue;
    }
    char buffer[4096];
    const ssize_t n = read(fds[0], buffer, sizeof buffer);
    if (n <= 0) break;
    run.output.append(buffer, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  run.seconds = now_s() - start_s;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  run.killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
  return run;
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Every file under `dir` with its bytes: equal snapshots mean the folder is untouched.
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  std::error_code ec;
  for (const auto& entry : fs::recursive_directory_iterator(dir, ec))
    if (entry.is_regular_file()) files[fs::relative(entry.path(), dir).string()] = read_bytes(entry.path());
  return files;
}

// A small trial (12 frames of 320 x 256) and its scene, made once per test (CTest runs the tests of this
// file as separate processes, in parallel, so each has its own).
const fs::path& small_trial() {
  static const fs::path trial = [] {
    const fs::path dir = testing::scratch_dir(
        "faults", std::string("source-") + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::ofstream(dir / "scene.yaml")
        << R"(calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}
tissue: {E_Pa: 1.0e6, nu: 0.4, depth_m: 0.002}
reference_pattern: {roi_px: [0, 0, 320, 24]}
compute: [contact, tracking, strain]
synthesis:
  seed: 7
  image: {width_px: 320, height_px: 256, bit_depth: 16}
  timing: {frames: 12, frame_rate_hz: 50}
  contact: {shape: hertz, normal_N: 0.5, radius_m: 0.01, border_irregularity: 0.02}
  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 5.0}
  fingerprint: {vignetting: 0.0, core_offset_mm: [0.2, -0.4]}
  sensor: {}
  channels: {}
  truth: {grid_step_px: 4}
)";
    const CliRun synth = run_cli(
        {"synth", "--scene", (dir / "scene.yaml").string(), "--out", (dir / "trial").string(), "--quiet"});
    EXPECT_EQ(synth.exit_code, 0) << synth.output;
    return dir / "trial";
  }();
  return trial;
}

std::vector<std::string> process_args(const fs::path& out) {
  return {"process", small_trial().string(), "--out", out.string(), "--quiet"};
}

bool mentions(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(Faults, ProcessRefusesAnOutputThatIsOrHoldsItsInput) {
  const fs::path dir = testing::scratch_dir("faults", "in_out");
  fs::copy(small_trial(), dir / "rec", fs::copy_options::recursive);
  const auto before = snapshot(dir / "rec");

  const CliRun same = run_cli({"process", (dir / "rec").string(), "--out", (dir / "rec").string()});
  EXPECT_EQ(same.exit_code, 1) << same.output;
  EXPECT_TRUE(mentions(same.output, "is the input")) << same.output;
  const CliRun holds = run_cli({"process", (dir / "rec").string(), "--out", dir.string()});
  EXPECT_EQ(holds.exit_code, 1) << holds.output;
  EXPECT_TRUE(mentions(holds.output, "contains the input")) << holds.output;
  const CliRun scene_inside =
      run_cli({"process", (dir / "rec" / "frames").string(), "--scene", (dir / "rec" / "scene.yaml").string(),
               "--out", (dir / "rec").string()});
  EXPECT_EQ(scene_inside.exit_code, 1) << scene_inside.output;
  EXPECT_EQ(snapshot(dir / "rec"), before);  // frames.csv and every other input byte for byte

  fs::create_directories(dir / "notes");
  std::ofstream(dir / "notes" / "notes.txt") << "mine";
  const CliRun foreign = run_cli({"process", (dir / "rec").string(), "--out", (dir / "notes").string()});
  EXPECT_EQ(foreign.exit_code, 1) << foreign.output;
  EXPECT_TRUE(mentions(foreign.output, "'notes.txt'")) << foreign.output;
  EXPECT_EQ(read_bytes(dir / "notes" / "notes.txt"), "mine");

  const CliRun synth =
      run_cli({"synth", "--scene", (dir / "rec" / "scene.yaml").string(), "--out", (dir / "rec").string()});
  EXPECT_EQ(synth.exit_code, 1) << synth.output;
  EXPECT_TRUE(mentions(synth.output, "holds the scene file")) << synth.output;
  EXPECT_EQ(snapshot(dir / "rec"), before);
}

TEST(Faults, DiskFullAtSeveralSizesKeepsTheEarlierResult) {
  const fs::path dir = testing::scratch_dir("faults", "disk_full");
  const fs::path out = dir / "out";
  const CliRun complete = run_cli(process_args(out));
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  const auto earlier = snapshot(out);
  ASSERT_TRUE(earlier.count("result.h5"));
  std::size_t largest = 0;
  for (const auto& [name, bytes] : earlier) largest = std::max(largest, bytes.size());
  for (const rlim_t limit : {rlim_t{0}, rlim_t{4096}, rlim_t{largest / 4}, rlim_t{largest - 1}}) {
    const CliRun run = run_cli(process_args(out), {.file_size_limit_bytes = limit});
    EXPECT_EQ(run.exit_code, 1) << "limit " << limit << ": " << run.output;
    EXPECT_TRUE(mentions(run.output, "File too large")) << "limit " << limit << ": " << run.output;
    EXPECT_EQ(snapshot(out), earlier) << "limit " << limit;
    EXPECT_FALSE(fs::exists(dir / "out.partial")) << "limit " << limit;
  }

  const fs::path trial_out = dir / "trial";
  const CliRun synth = run_cli(
      {"synth", "--scene", (small_trial() / "scene.yaml").string(), "--out", trial_out.string(), "--quiet"});
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const auto trial_before = snapshot(trial_out);
  for (const rlim_t limit : {rlim_t{0}, rlim_t{20000}, rlim_t{200000}}) {
    const CliRun run = run_cli(
        {"synth", "--scene", (small_trial() / "scene.yaml").string(), "--out", trial_out.string(), "--quiet"},
        {.file_size_limit_bytes = limit});
    EXPECT_EQ(run.exit_code, 1) << "limit " << limit << ": " << run.output;
    EXPECT_TRUE(mentions(run.output, "File too large")) << "limit " << limit << ": " << run.output;
    EXPECT_EQ(snapshot(trial_out), trial_before) << "limit " << limit;
    EXPECT_FALSE(fs::exists(dir / "trial.partial")) << "limit " << limit;
  }

  // A recording that hits the limit: every frame received is accounted for (saved, not saved, incomplete
  // or dropped), the one whose write failed included.
  for (const rlim_t limit : {rlim_t{20000}, rlim_t{50000}}) {
    const fs::path rec = dir / ("rec_" + std::to_string(limit));
    const CliRun run = run_cli({"record", small_trial().string(), "--out", rec.string(), "--quiet"},
                               {.file_size_limit_bytes = limit});
    EXPECT_EQ(run.exit_code, 1) << "limit " << limit << ": " << run.output;
    const nlohmann::json r = nlohmann::json::parse(read_bytes(rec / "recording.json"), nullptr, false);
    ASSERT_TRUE(r.is_object()) << "limit " << limit;
    EXPECT_EQ(r.value("frames_received", -1), r.value("frames_saved", 0) + r.value("frames_not_saved", 0) +
                                                  r.value("frames_incomplete", 0) +
                                                  r.value("frames_dropped_host", 0))
        << r.dump();
  }

  const CliRun model = run_cli({"model", "cattaneo-mindlin", "--normal-N", "2", "--tangential-N", "1.2",
                                "--radius-m", "0.01", "--young-Pa", "1e6", "--poisson", "0.4", "--friction",
                                "1.0", "--grid", "64", "--out", (dir / "model").string()},
                               {.file_size_limit_bytes = 1000});
  EXPECT_EQ(model.exit_code, 1) << model.output;
  EXPECT_TRUE(mentions(model.output, "File too large")) << model.output;
  EXPECT_FALSE(fs::exists(dir / "model" / "model.h5"));
  EXPECT_FALSE(fs::exists(dir / "model" / "model.h5.partial"));
}

// Leaves about `free_bytes` free on the filesystem holding `dir` by writing a filler file.
void fill_leaving(const fs::path& dir, std::size_t free_bytes) {
  struct statvfs stat {};
  ASSERT_EQ(statvfs(dir.c_str(), &stat), 0);
  const std::size_t available = static_cast<std::size_t>(stat.f_bavail) * stat.f_frsize;
  ASSERT_GT(available, free_bytes);
  std::ofstream filler(dir / "filler", std::ios::binary | std::ios::trunc);
  const std::string block(available - free_bytes, '\0');
  filler.write(block.data(), static_cast<std::streamsize>(block.size()));
}

// A real full disk (ENOSPC), on a 4 MB tmpfs: needs the right to mount (root in a privileged container);
// skipped otherwise, the file-size limit above covering the same code paths.
TEST(Faults, FullTmpfsIsNamedAndKeepsTheEarlierResult) {
  const fs::path dir = testing::scratch_dir("faults", "tmpfs");
  const fs::path disk = dir / "disk";
  fs::create_directories(disk);
  if (geteuid() != 0 || mount("tirstrain-test", disk.c_str(), "tmpfs", 0, "size=4m") != 0)
    GTEST_SKIP() << "cannot mount a tmpfs here (not root, or no CAP_SYS_ADMIN)";
  struct Unmount {
    const fs::path& at;
    ~Unmount() { umount2(at.c_str(), MNT_DETACH); }
  } unmount{disk};
  const fs::path out = disk / "out";
  const CliRun complete = run_cli(process_args(out));
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  const auto earlier = snapshot(out);
  for (const std::size_t free_bytes : {std::size_t{0}, std::size_t{16} << 10, std::size_t{300} << 10}) {
    fill_leaving(disk, free_bytes);
    const CliRun run = run_cli(process_args(out));
    EXPECT_EQ(run.exit_code, 1) << free_bytes << " bytes free: " << run.output;
    EXPECT_TRUE(mentions(run.output, "No space left on device"))
        << free_bytes << " bytes free: " << run.output;
    EXPECT_EQ(snapshot(out), earlier) << free_bytes << " bytes free";
    EXPECT_FALSE(fs::exists(disk / "out.partial")) << free_bytes << " bytes free";
    fs::remove(disk / "filler");
  }
  // synth's images are written by a codec that reports no cause: the disk is named all the same.
  for (const std::size_t free_bytes : {std::size_t{16} << 10, std::size_t{300} << 10}) {
    fill_leaving(disk, free_bytes);
    const CliRun synth = run_cli({"synth", "--scene", (small_trial() / "scene.yaml").string(), "--out",
                                  (disk / "trial").string(), "--quiet"});
    EXPECT_EQ(synth.exit_code, 1) << free_bytes << " bytes free: " << synth.output;
    EXPECT_TRUE(mentions(synth.output, "No space left on device"))
        << free_bytes << " bytes free: " << synth.output;
    fs::remove(disk / "filler");
  }
}

TEST(Faults, ReadOnlyOutputFolderIsNamedAndLeftAlone) {
  const fs::path dir = testing::scratch_dir("faults", "read_only");
  const fs::path parent = dir / "results";
  const fs::path out = parent / "out";
  const CliRun complete = run_cli(process_args(out));
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  const auto earlier = snapshot(out);
  bool mounted = false;
  if (geteuid() == 0) {
    mounted = mount(parent.c_str(), parent.c_str(), nullptr, MS_BIND, nullptr) == 0;
    if (mounted && mount(nullptr, parent.c_str(), nullptr, MS_REMOUNT | MS_BIND | MS_RDONLY, nullptr) != 0) {
      umount(parent.c_str());
      mounted = false;
    }
    if (!mounted) GTEST_SKIP() << "running as root without the right to mount: mode bits would not bind";
  } else {
    fs::permissions(parent, fs::perms::owner_read | fs::perms::owner_exec);
  }
  const CliRun run = run_cli(process_args(out));
  const CliRun synth = run_cli({"synth", "--scene", (small_trial() / "scene.yaml").string(), "--out",
                                (parent / "trial").string(), "--quiet"});
  const auto after = snapshot(out);
  if (mounted) umount(parent.c_str());
  fs::permissions(parent, fs::perms::owner_all);
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_TRUE(mentions(run.output, mounted ? "Read-only file system" : "Permission denied")) << run.output;
  EXPECT_TRUE(mentions(run.output, "out")) << run.output;
  EXPECT_EQ(after, earlier);
  EXPECT_EQ(synth.exit_code, 1) << synth.output;
  EXPECT_TRUE(mentions(synth.output, mounted ? "Read-only file system" : "Permission denied"))
      << synth.output;
}

// Kill times spread over a complete run's duration, the same on every run of the test.
std::vector<double> kill_points(double run_s, int count) {
  std::mt19937 random(39);
  std::uniform_real_distribution<double> uniform(0.0, 1.1 * run_s);
  std::vector<double> points(static_cast<std::size_t>(count));
  for (double& t : points) t = uniform(random);
  return points;
}

constexpr int kKills = 20;

// After a kill the folder holds one whole result: the earlier one byte for byte, or, when the kill came
// after the swap, the new one: the same files, with `stable` (a file no clock or run time enters) the same.
void expect_one_whole_result(const std::map<std::string, std::string>& now,
                             const std::map<std::string, std::string>& earlier, const std::string& stable,
                             double killed_at_s) {
  if (now == earlier) return;
  std::vector<std::string> now_names, earlier_names;
  for (const auto& entry : now) now_names.push_back(entry.first);
  for (const auto& entry : earlier) earlier_names.push_back(entry.first);
  EXPECT_EQ(now_names, earlier_names) << "killed at " << killed_at_s << " s";
  ASSERT_TRUE(now.count(stable) && earlier.count(stable)) << stable;
  EXPECT_EQ(now.at(stable), earlier.at(stable)) << "killed at " << killed_at_s << " s";
}

TEST(Faults, ProcessKilledAnywhereLeavesTheEarlierResult) {
  const fs::path dir = testing::scratch_dir("faults", "kill_process");
  const fs::path out = dir / "out";
  const CliRun complete = run_cli(process_args(out));
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  const auto earlier = snapshot(out);
  int killed = 0;
  for (const double t : kill_points(complete.seconds, kKills)) {
    const CliRun run = run_cli(process_args(out), {.kill_after_s = t});
    killed += run.killed;
    if (!run.killed) {
      EXPECT_EQ(run.exit_code, 0) << "killed at " << t << " s: " << run.output;
    }
    expect_one_whole_result(snapshot(out), earlier, "frames.csv", t);
  }
  EXPECT_GE(killed, kKills / 2);
  const CliRun again = run_cli(process_args(out));
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_FALSE(fs::exists(dir / "out.partial"));  // a new run clears what a killed one left
}

// A run killed part way leaves, apart from any complete result, the frames before its last flush readable
// and marked incomplete (result.h5.partial `complete` 0 and `frames_written`, summary.json `complete:
// false`), each of them equal to the complete run's.
TEST(Faults, ProcessKilledMidRunLeavesItsFlushedFramesReadableAndMarkedIncomplete) {
  const fs::path dir = testing::scratch_dir("faults", "kill_partial");
  const fs::path reference = dir / "reference", out = dir / "out", staged = dir / "out.partial";
  std::vector<std::string> args = process_args(reference);
  args.insert(args.end(), {"--overlay", "none", "--flush-every-frames", "3"});
  const CliRun complete = run_cli(args);
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  const H5Reader whole((reference / "result.h5").string());
  H5Shape whole_shape;
  const std::vector<double> whole_t = whole.read_doubles("/frames/t_s");
  const std::vector<double> whole_positions = whole.read_doubles("/tracks/position_px", &whole_shape);
  ASSERT_EQ(whole_t.size(), 12u);

  args[3] = out.string();
  // Killed as soon as the first flush has said so: the frames before it must be readable.
  const CliRun run = run_cli(args, {.kill_once_exists = staged / "summary.json"});
  ASSERT_TRUE(run.killed) << "the run ended before it was killed: " << run.output;
  EXPECT_FALSE(fs::exists(out));  // nothing incomplete where the complete result would be
  std::ifstream summary_file(staged / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(summary_file);
  EXPECT_FALSE(summary.at("complete").get<bool>());
  const auto k = summary.at("frames_written").get<std::size_t>();
  std::cout << "  killed after the flush at frame " << k << "\n";
  EXPECT_GE(k, 3u);
  EXPECT_LT(k, 12u);
  const H5Reader partial((staged / "result.h5.partial").string());
  EXPECT_EQ(partial.attribute_number("/", "complete"), 0.0);
  EXPECT_GE(partial.attribute_number("/", "frames_written"), static_cast<double>(k));
  const std::vector<double> t = partial.read_doubles("/frames/t_s");
  ASSERT_GE(t.size(), k);
  for (std::size_t f = 0; f < k; ++f) EXPECT_EQ(t[f], whole_t[f]) << "frame " << f;
  H5Shape shape;
  const std::vector<double> positions = partial.read_doubles("/tracks/position_px", &shape);
  ASSERT_EQ(shape.size(), 3u);
  ASSERT_GE(shape[0], k);
  const std::size_t tracks = std::min(shape[1], whole_shape[1]);
  ASSERT_GT(tracks, 100u);
  int differing = 0;
  for (std::size_t f = 0; f < k; ++f)
    for (std::size_t i = 0; i < 2 * tracks; ++i) {
      const double a = positions[f * shape[1] * 2 + i], b = whole_positions[f * whole_shape[1] * 2 + i];
      differing += !(a == b || (std::isnan(a) && std::isnan(b)));
    }
  EXPECT_EQ(differing, 0);
}

// Every dataset of a result file (groups walked down to their datasets).
std::vector<std::string> datasets_of(const H5Reader& file, const std::string& group = "/") {
  std::vector<std::string> names;
  for (const std::string& member : file.members(group)) {
    const std::string name = (group == "/" ? "" : group) + "/" + member;
    bool is_group = false;
    try {
      file.members(name);
      is_group = true;
    } catch (const std::exception&) {
    }
    if (is_group) {
      for (const std::string& inner : datasets_of(file, name)) names.push_back(inner);
    } else {
      names.push_back(name);
    }
  }
  return names;
}

// Killed once its first checkpoint is on disk, then resumed: result.h5 holds every dataset the
// uninterrupted run writes with every value equal (NaN where it has NaN), and frames.csv is the same byte for
// byte. With channels and the model fit, so that every stage is continued.
TEST(Faults, ProcessKilledThenResumedGivesTheUninterruptedResult) {
  const fs::path dir = testing::scratch_dir("faults", "resume");
  const fs::path reference = dir / "reference", out = dir / "out", staged = dir / "out.partial";
  std::vector<std::string> args = process_args(reference);
  args.insert(args.end(), {"--overlay", "none", "--flush-every-frames", "3", "--checkpoint-every-s", "0",
                           "--compute", "channels", "fit"});
  const CliRun complete = run_cli(args);
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  args[3] = out.string();
  // Its summary is written right after its first checkpoint.
  const CliRun killed = run_cli(args, {.kill_once_exists = staged / "summary.json"});
  ASSERT_TRUE(killed.killed) << "the run ended before it was killed: " << killed.output;
  ASSERT_TRUE(fs::exists(staged / "checkpoint.bin"));
  std::ifstream partial_summary(staged / "summary.json");
  const auto resumable = nlohmann::json::parse(partial_summary).at("resumable_from_frame").get<int>();
  EXPECT_GE(resumable, 3);
  EXPECT_LT(resumable, 12);

  args.push_back("--resume");
  const CliRun resumed = run_cli(args);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_FALSE(fs::exists(staged));
  EXPECT_FALSE(fs::exists(out / "checkpoint.bin"));
  std::ifstream summary_file(out / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(summary_file);
  EXPECT_TRUE(summary.at("complete").get<bool>());
  const int resumed_from = summary.at("resumed_from_frame").get<int>();
  EXPECT_GE(resumed_from, resumable);
  std::cout << "  resumed after frame " << resumed_from << " of 12\n";

  const H5Reader whole((reference / "result.h5").string()), continued((out / "result.h5").string());
  const std::vector<std::string> names = datasets_of(whole);
  EXPECT_EQ(datasets_of(continued), names);
  int compared = 0, differing = 0;
  for (const std::string& name : names) {
    H5Shape a_shape, b_shape;
    const std::vector<double> a = whole.read_doubles(name, &a_shape);
    const std::vector<double> b = continued.read_doubles(name, &b_shape);
    ASSERT_EQ(a_shape, b_shape) << name;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const bool same = a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i]));
      differing += !same;
      if (!same && differing < 5) ADD_FAILURE() << name << "[" << i << "]: " << a[i] << " against " << b[i];
    }
    ++compared;
  }
  EXPECT_EQ(differing, 0);
  EXPECT_GT(compared, 40);  // /frames, /contact, /tracks, /plate, /mesh, /strain, /energy, /channels, /fit
  EXPECT_EQ(read_bytes(out / "frames.csv"), read_bytes(reference / "frames.csv"));
}

// A kill while HDF5 rewrites a chunk can leave the interrupted run's flushed rows unreadable (the format is
// not written crash-safe): here its file is cut in half. The resumed run says so and starts again from the
// first frame, and gives the uninterrupted result.
TEST(Faults, ResumeOfADamagedInterruptedResultStartsAgain) {
  const fs::path dir = testing::scratch_dir("faults", "resume_damaged");
  const fs::path reference = dir / "reference", out = dir / "out", staged = dir / "out.partial";
  std::vector<std::string> args = process_args(reference);
  args.erase(std::find(args.begin(), args.end(), "--quiet"));  // the restart is said on the console
  args.insert(args.end(), {"--overlay", "none", "--flush-every-frames", "3", "--checkpoint-every-s", "0"});
  ASSERT_EQ(run_cli(args).exit_code, 0);
  args[3] = out.string();
  const CliRun killed = run_cli(args, {.kill_once_exists = staged / "summary.json"});
  ASSERT_TRUE(killed.killed) << killed.output;
  const fs::path partial = staged / "result.h5.partial";
  ASSERT_TRUE(fs::exists(partial));
  fs::resize_file(partial, fs::file_size(partial) / 2);
  args.push_back("--resume");
  const CliRun resumed = run_cli(args);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_TRUE(mentions(resumed.output, "starting again from the first frame")) << resumed.output;
  EXPECT_FALSE(fs::exists(staged));
  EXPECT_EQ(read_bytes(out / "frames.csv"), read_bytes(reference / "frames.csv"));
}

// A frame of the input replaced after the run was killed: the checkpoint is another input's, so --resume is
// refused (a resumed run would mix the two inputs' frames).
TEST(Faults, ResumeRefusesAnInputWhoseFilesChanged) {
  const fs::path dir = testing::scratch_dir("faults", "resume_changed");
  const fs::path input = dir / "input", out = dir / "out", staged = dir / "out.partial";
  fs::copy(small_trial(), input, fs::copy_options::recursive);
  std::vector<std::string> args = {
      "process", input.string(),         "--out", out.string(),           "--quiet", "--overlay",
      "none",    "--flush-every-frames", "3",     "--checkpoint-every-s", "0"};
  const CliRun killed = run_cli(args, {.kill_once_exists = staged / "summary.json"});
  ASSERT_TRUE(killed.killed) << killed.output;
  std::vector<fs::path> frames;
  for (const auto& entry : fs::directory_iterator(input / "frames")) frames.push_back(entry.path());
  std::sort(frames.begin(), frames.end());
  ASSERT_GE(frames.size(), 3u);
  fs::copy_file(frames[2], frames[1], fs::copy_options::overwrite_existing);
  args.push_back("--resume");
  const CliRun refused = run_cli(args);
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_TRUE(mentions(refused.output, "another input, scene or options")) << refused.output;
}

TEST(Faults, ResumeRefusesAnInterruptedRunOfOtherOptionsAndKeepsIt) {
  const fs::path dir = testing::scratch_dir("faults", "resume_other");
  const fs::path out = dir / "out", staged = dir / "out.partial";
  std::vector<std::string> args = process_args(out);
  args.insert(args.end(), {"--overlay", "none", "--flush-every-frames", "3", "--checkpoint-every-s", "0"});
  const CliRun killed = run_cli(args, {.kill_once_exists = staged / "summary.json"});
  ASSERT_TRUE(killed.killed) << killed.output;
  ASSERT_TRUE(fs::exists(staged / "checkpoint.bin"));
  const auto before = snapshot(staged);
  std::vector<std::string> other = args;
  other.insert(other.end(), {"--preset", "delhaye2016", "--resume"});
  const CliRun refused = run_cli(other);
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_TRUE(mentions(refused.output, "another input, scene or options")) << refused.output;
  EXPECT_EQ(snapshot(staged), before);  // the interrupted run, untouched, can still be resumed
  args.push_back("--resume");
  const CliRun resumed = run_cli(args);
  EXPECT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_TRUE(fs::exists(out / "result.h5"));
}

TEST(Faults, SynthKilledAnywhereLeavesTheEarlierTrial) {
  const fs::path dir = testing::scratch_dir("faults", "kill_synth");
  const fs::path out = dir / "trial";
  const std::vector<std::string> args = {"synth", "--scene",    (small_trial() / "scene.yaml").string(),
                                         "--out", out.string(), "--quiet"};
  const CliRun complete = run_cli(args);
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  const auto earlier = snapshot(out);
  int killed = 0;
  for (const double t : kill_points(complete.seconds, kKills)) {
    const CliRun run = run_cli(args, {.kill_after_s = t});
    killed += run.killed;
    if (!run.killed) {
      EXPECT_EQ(run.exit_code, 0) << run.output;
    }
    expect_one_whole_result(snapshot(out), earlier, "frames/000011.png", t);
  }
  EXPECT_GE(killed, kKills / 2);
}

// Rows of a recording's frames.csv whose image is said to be saved must have a whole image behind them.
void expect_consistent_recording(const fs::path& rec, double killed_at_s) {
  std::ifstream csv(rec / "frames.csv");
  std::string line;
  std::getline(csv, line);
  if (line.empty()) return;  // killed before the header
  ASSERT_EQ(line.rfind("index,t_s,device_frame_id", 0), 0u) << line;
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    std::vector<std::string> cells;
    std::stringstream cells_in(line);
    for (std::string cell; std::getline(cells_in, cell, ',');) cells.push_back(cell);
    ASSERT_EQ(cells.size(), 9u) << "killed at " << killed_at_s << " s: half a row: " << line;
    if (cells[8] != "1") continue;
    char name[32];
    std::snprintf(name, sizeof name, "%06lld.tif", std::stoll(cells[2]));
    const cv::Mat image = cv::imread((rec / "frames" / name).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(image.cols, 320) << "killed at " << killed_at_s << " s: " << name;
  }
}

TEST(Faults, RecordKilledAnywhereKeepsAConsistentFolder) {
  const fs::path dir = testing::scratch_dir("faults", "kill_record");
  const CliRun complete = run_cli({"record", small_trial().string(), "--out", (dir / "complete").string()});
  ASSERT_EQ(complete.exit_code, 0) << complete.output;
  ASSERT_TRUE(fs::exists(dir / "complete" / "recording.json"));
  const nlohmann::json complete_report =
      nlohmann::json::parse(read_bytes(dir / "complete" / "recording.json"));
  int killed = 0, index = 0;
  for (const double t : kill_points(complete.seconds, kKills)) {
    const fs::path rec = dir / ("rec" + std::to_string(index++));
    const CliRun run =
        run_cli({"record", small_trial().string(), "--out", rec.string()}, {.kill_after_s = t});
    killed += run.killed;
    if (!run.killed) {
      EXPECT_EQ(run.exit_code, 0) << run.output;
    }
    // Killed, the recording says it finished only if it did: recording.json is written last, whole (its
    // final name comes with its last byte), so a kill that lands after it, while the process exits, leaves a
    // complete recording.
    if (run.killed && fs::exists(rec / "recording.json")) {
      const nlohmann::json report = nlohmann::json::parse(read_bytes(rec / "recording.json"), nullptr, false);
      ASSERT_FALSE(report.is_discarded()) << "killed at " << t << " s: a recording.json cut short";
      EXPECT_EQ(report.value("stop_reason", ""), "end of stream") << "killed at " << t << " s";
      EXPECT_EQ(report.value("frames_saved", -1), complete_report.value("frames_saved", -2))
          << "killed at " << t << " s";
    }
    expect_consistent_recording(rec, t);
  }
  EXPECT_GE(killed, kKills / 2);
}

// The scene's pattern band lies outside the camera image: the analysis fails on the first frame. The
// recording goes on to the end and says so in recording.json; the analysis error is shown and the exit code
// says the run was not all it was asked to be.
TEST(Faults, LiveAnalysisErrorLeavesTheRecordingWhole) {
  const fs::path dir = testing::scratch_dir("faults", "live");
  std::string scene = read_bytes(small_trial() / "scene.yaml");
  const std::size_t roi = scene.find("roi_px:");
  ASSERT_NE(roi, std::string::npos) << scene;
  scene.replace(roi, scene.find(']', roi) - roi + 1, "roi_px: [5000, 5000, 100, 20]");
  std::ofstream(dir / "outside.yaml") << scene;
  const fs::path rec = dir / "rec";
  const CliRun run = run_cli({"live", small_trial().string(), "--scene", (dir / "outside.yaml").string(),
                              "--record", rec.string(), "--no-window", "--quiet"});
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_TRUE(mentions(run.output, "analysis stopped")) << run.output;
  EXPECT_TRUE(mentions(run.output,
                       "'reference_pattern.roi_px': the pattern band [5000, 5000, 100, 20] (x, y, width, "
                       "height) lies outside the 320 x 256 px frames"))
      << run.output;
  EXPECT_TRUE(mentions(run.output, "is complete")) << run.output;
  EXPECT_TRUE(fs::exists(rec / "recording.json")) << run.output;
  expect_consistent_recording(rec, -1.0);
  std::ifstream csv(rec / "frames.csv");
  int lines = 0;
  for (std::string line; std::getline(csv, line);) ++lines;
  EXPECT_EQ(lines, 1 + 12);  // header and every frame of the source

  // process says the same of the same scene, instead of an OpenCV assertion.
  const CliRun process =
      run_cli({"process", small_trial().string(), "--scene", (dir / "outside.yaml").string(), "--out",
               (dir / "out").string(), "--quiet"});
  EXPECT_EQ(process.exit_code, 1) << process.output;
  EXPECT_TRUE(mentions(process.output, "lies outside the 320 x 256 px frames")) << process.output;
  EXPECT_FALSE(fs::exists(dir / "out" / "result.h5"));

  // A band only partly inside (written for a wider camera) is refused too, not clipped.
  scene.replace(scene.find("roi_px:"), scene.find(']', scene.find("roi_px:")) - scene.find("roi_px:") + 1,
                "roi_px: [0, 0, 400, 24]");
  std::ofstream(dir / "wider.yaml") << scene;
  const CliRun wider = run_cli({"process", small_trial().string(), "--scene", (dir / "wider.yaml").string(),
                                "--out", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(wider.exit_code, 1) << wider.output;
  EXPECT_TRUE(
      mentions(wider.output, "[0, 0, 400, 24] (x, y, width, height) reaches outside the 320 x 256 px"))
      << wider.output;
  EXPECT_FALSE(fs::exists(dir / "out" / "result.h5"));
}

}  // namespace
}  // namespace tirstrain
