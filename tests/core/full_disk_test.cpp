// The writers on a full disk. The disk is made "full" with the file-size limit (RLIMIT_FSIZE, SIGXFSZ
// ignored, so a write past it fails with EFBIG), which an unprivileged test can set in a child process; a
// real full filesystem (ENOSPC) takes the same path through write(2). HDF5 writing straight to disk crashes
// on this path (SIGSEGV in DataSet::~DataSet after a failed H5Dclose).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain {
namespace {

namespace fs = std::filesystem;

struct ChildResult {
  bool exited = false;  // false: killed by a signal (a crash)
  int exit_code = -1;
  std::string message;  // what the child wrote to its pipe: the Error's text
};

// Runs `body` in a child process whose files may not grow past `limit_bytes`. The child reports the
// message of the Error `body` throws (exit 3) or nothing (exit 0).
ChildResult run_with_file_size_limit(rlim_t limit_bytes, const std::function<void()>& body) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{limit_bytes, limit_bytes};
    setrlimit(RLIMIT_FSIZE, &limit);
    int code = 0;
    std::string message;
    try {
      body();
    } catch (const Error& e) {
      message = e.what();
      code = 3;
    }
    if (!message.empty() && write(fds[1], message.data(), message.size()) < 0) code = 4;
    _exit(code);
  }
  close(fds[1]);
  ChildResult result;
  char buffer[1024];
  ssize_t n = 0;
  while ((n = read(fds[0], buffer, sizeof buffer)) > 0)
    result.message.append(buffer, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  result.exited = WIFEXITED(status);
  result.exit_code = result.exited ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

// Doubles that deflate cannot shrink much, so the file is about as large as the data.
std::vector<double> incompressible(std::size_t n) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<double> values(n);
  for (double& v : values) v = uniform(random);
  return values;
}

TEST(FullDisk, HdfWriterReportsTheCauseAndLeavesNoFile) {
  const fs::path dir = testing::scratch_dir("core", "full_disk_h5");
  const std::string path = (dir / "result.h5").string();
  for (const rlim_t limit : {rlim_t{0}, rlim_t{4096}, rlim_t{256 * 1024}}) {
    const ChildResult child = run_with_file_size_limit(limit, [&] {
      H5Writer h5(path);
      const std::vector<double> data = incompressible(200000);  // 1.6 MB
      h5.write("/frames/t_s", std::span<const double>(data), {data.size()});
      h5.attribute("/", "format", "tirstrain result");
      h5.commit();
    });
    EXPECT_TRUE(child.exited) << "limit " << limit << ": killed by signal " << child.exit_code - 128;
    EXPECT_EQ(child.exit_code, 3) << "limit " << limit;
    EXPECT_NE(child.message.find("File too large"), std::string::npos) << child.message;
    EXPECT_NE(child.message.find("result.h5"), std::string::npos) << child.message;
    EXPECT_FALSE(fs::exists(path)) << "limit " << limit;
    EXPECT_FALSE(fs::exists(path + ".partial")) << "limit " << limit;
  }
}

TEST(FullDisk, CsvAndTextWritersReportTheCauseAndLeaveNoPartialFile) {
  const fs::path dir = testing::scratch_dir("core", "full_disk_text");
  const std::string csv_path = (dir / "frames.csv").string();
  const std::string json_path = (dir / "summary.json").string();
  const ChildResult csv = run_with_file_size_limit(1000, [&] {
    CsvWriter out(csv_path, {"t_s", "normal_N"});
    for (int i = 0; i < 10000; ++i) out.row({0.001 * i, 1.0 / (i + 1)});
    out.commit();
  });
  EXPECT_TRUE(csv.exited);
  EXPECT_EQ(csv.exit_code, 3);
  EXPECT_NE(csv.message.find("File too large"), std::string::npos) << csv.message;
  EXPECT_FALSE(fs::exists(csv_path));
  EXPECT_FALSE(fs::exists(csv_path + ".partial"));

  const ChildResult text =
      run_with_file_size_limit(100, [&] { write_text_file(json_path, std::string(5000, 'x')); });
  EXPECT_EQ(text.exit_code, 3);
  EXPECT_NE(text.message.find("File too large"), std::string::npos) << text.message;
  EXPECT_FALSE(fs::exists(json_path + ".partial"));
}

TEST(FullDisk, WritesWithinTheLimitSucceed) {
  const fs::path dir = testing::scratch_dir("core", "full_disk_room");
  const std::string path = (dir / "result.h5").string();
  const ChildResult child = run_with_file_size_limit(4u << 20, [&] {
    H5Writer h5(path);
    const std::vector<double> data = incompressible(1000);
    h5.write("/x", std::span<const double>(data), {data.size()});
    h5.commit();
  });
  EXPECT_EQ(child.exit_code, 0) << child.message;
  const H5Reader reader(path);
  EXPECT_EQ(reader.read_doubles("/x"), incompressible(1000));
}

TEST(StagingDirectory, EarlierOutputStaysWholeUntilTheSwap) {
  const fs::path dir = testing::scratch_dir("core", "staging_swap");
  const std::string final_dir = (dir / "out").string();
  fs::create_directories(final_dir);
  std::ofstream(final_dir + "/old.txt") << "earlier";
  {
    StagingDirectory stage(final_dir);
    std::ofstream(stage.path() + "/new.txt") << "new";
    EXPECT_TRUE(fs::exists(final_dir + "/old.txt"));  // untouched while the new output is built
    EXPECT_FALSE(fs::exists(final_dir + "/new.txt"));
  }
  EXPECT_TRUE(fs::exists(final_dir + "/old.txt"));  // abandoned: the earlier output is still whole
  {
    StagingDirectory stage(final_dir);
    std::ofstream(stage.path() + "/new.txt") << "new";
    stage.commit();
  }
  EXPECT_TRUE(fs::exists(final_dir + "/new.txt"));
  EXPECT_FALSE(fs::exists(final_dir + "/old.txt"));
  EXPECT_FALSE(fs::exists(final_dir + ".partial"));
}

// A second writer into the same output while the first is building it is refused, and the first's staging
// folder is left as it was; once the first is done, the output can be written again.
TEST(StagingDirectory, ASecondRunIntoTheSameOutputIsRefused) {
  const fs::path dir = testing::scratch_dir("core", "staging_lock");
  const std::string final_dir = (dir / "out").string();
  {
    StagingDirectory first(final_dir);
    std::ofstream(first.path() + "/result.txt") << "first";
    try {
      StagingDirectory second(final_dir);
      ADD_FAILURE() << "a second staging directory was created for the same output";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("another tirstrain run is writing this output"), std::string::npos)
          << e.what();
    }
    EXPECT_TRUE(fs::exists(first.path() + "/result.txt"));
    first.commit();
  }
  EXPECT_TRUE(fs::exists(final_dir + "/result.txt"));
  EXPECT_FALSE(fs::exists(final_dir + "/" + StagingDirectory::kStagingMarker));  // not in the finished output
  EXPECT_NO_THROW(StagingDirectory again(final_dir));
}

// "<out>.partial" left by an interrupted run (it carries the marker) is cleared by the next run; one that
// holds anything else is someone's folder, and is refused and left untouched.
TEST(StagingDirectory, ClearsAnInterruptedRunsLeftoverButNotAForeignFolder) {
  const fs::path dir = testing::scratch_dir("core", "staging_leftover");
  const std::string final_dir = (dir / "out").string();
  fs::create_directories(final_dir + ".partial");
  std::ofstream(final_dir + ".partial/" + StagingDirectory::kStagingMarker) << "x";
  std::ofstream(final_dir + ".partial/result.h5.partial") << "cut short";
  {
    StagingDirectory stage(final_dir);
    EXPECT_FALSE(fs::exists(stage.path() + "/result.h5.partial"));
  }
  const std::string foreign = (dir / "mine").string();
  fs::create_directories(foreign + ".partial");
  std::ofstream(foreign + ".partial/notes.txt") << "keep";
  EXPECT_THROW(StagingDirectory stage(foreign), Error);
  EXPECT_TRUE(fs::exists(foreign + ".partial/notes.txt"));
}

// An output given as a link to a folder is written into the folder, and the link stays a link.
TEST(StagingDirectory, FollowsALinkToAFolder) {
  const fs::path dir = testing::scratch_dir("core", "staging_link");
  fs::create_directories(dir / "real");
  fs::create_directory_symlink(dir / "real", dir / "link");
  {
    StagingDirectory stage((dir / "link").string());
    std::ofstream(stage.path() + "/result.txt") << "r";
    stage.commit();
  }
  EXPECT_TRUE(fs::is_symlink(dir / "link"));
  EXPECT_TRUE(fs::exists(dir / "real" / "result.txt"));
}

TEST(RecordedPath, NamesTheFinalPlaceOfWholeStagingFolderNamesOnly) {
  const std::vector<StagedFolder> nested = {{"/o/v.partial", "/o/v"}, {"/b.partial", "/b"}};
  EXPECT_EQ(recorded_path("/o/v.partial/trial", nested), "/o/v/trial");
  EXPECT_EQ(recorded_path("image folder /o/v.partial/trial/frames (t_s from /o/v.partial/trial/frames.csv)",
                          nested),
            "image folder /o/v/trial/frames (t_s from /o/v/trial/frames.csv)");
  EXPECT_EQ(recorded_path("/o/v.partial", nested), "/o/v");
  EXPECT_EQ(recorded_path("/b.partial/runs/x", nested), "/b/runs/x");      // the outer folder, next in order
  EXPECT_EQ(recorded_path("/o/v.partial2/x", nested), "/o/v.partial2/x");  // another folder's name
  EXPECT_EQ(recorded_path("/elsewhere/trial", nested), "/elsewhere/trial");
  EXPECT_EQ(recorded_path("/o/v.partial/x", {}), "/o/v.partial/x");
}

TEST(PathIsWithin, ComparesResolvedPaths) {
  const fs::path dir = testing::scratch_dir("core", "within");
  fs::create_directories(dir / "a" / "b");
  EXPECT_TRUE(path_is_within((dir / "a").string(), (dir / "a").string()));
  EXPECT_TRUE(path_is_within((dir / "a" / "b").string(), (dir / "a").string()));
  EXPECT_TRUE(path_is_within((dir / "a" / "b" / ".." / "b").string(), (dir / "a/").string()));
  EXPECT_FALSE(path_is_within((dir / "a").string(), (dir / "a" / "b").string()));
  EXPECT_FALSE(path_is_within((dir / "ab").string(), (dir / "a").string()));
}

}  // namespace
}  // namespace tirstrain
