#pragma once
// Helpers for the Aravis tests: the namespace guard, fake cameras (in-process and the arv-fake-gv-camera
// process), and running the CLI in the background.
#include <arv.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace tirstrain::testing {

// Empty when the test runs inside its private loopback-only namespace; otherwise why it does not.
std::string& namespace_problem();

#define TIRSTRAIN_REQUIRE_NETNS()                                \
  do {                                                           \
    if (!::tirstrain::testing::namespace_problem().empty())      \
      GTEST_SKIP() << ::tirstrain::testing::namespace_problem(); \
  } while (0)

inline std::string test_dir(const std::string& name) {
  const std::string dir = std::string(TIRSTRAIN_TEST_TMP) + "/capture_aravis/" + name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(std::filesystem::path(dir).parent_path());
  return dir;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A child process with stdout+stderr in a log file. Killed (SIGKILL) and reaped on destruction.
class Child {
 public:
  Child(const std::vector<std::string>& argv, const std::string& log_path) : log_path_(log_path) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    if (posix_spawnp(&pid_, args[0], &actions, nullptr, args.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~Child() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  pid_t pid() const { return pid_; }
  void kill_now() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
      reaped_ = true;
    }
  }
  // Exit code, 128+signal, or -1 if still running after timeout_s (then it is killed).
  int wait(double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      int status = 0;
      const pid_t r = ::waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        reaped_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    kill_now();
    return -1;
  }
  std::string log() const { return read_text(log_path_); }

 private:
  std::string log_path_;
  pid_t pid_ = -1;
  bool reaped_ = false;
};

// Waits until a GigE Vision device answers on 127.0.0.1 (the camera process needs a moment to bind).
inline bool wait_for_camera(double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    GError* error = nullptr;
    ArvCamera* camera = arv_camera_new("127.0.0.1", &error);
    g_clear_error(&error);
    if (camera != nullptr) {
      g_object_unref(camera);
      return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

// arv-fake-gv-camera-0.8 as a separate process (it can be killed, and -r drops packets).
class FakeCameraProcess {
 public:
  explicit FakeCameraProcess(const std::string& name, int lost_packets_per_thousand = 0)
      : child_(make_args(lost_packets_per_thousand), log_path(name)) {}
  bool ready() { return child_.pid() > 0 && wait_for_camera(10.0); }
  void kill_now() { child_.kill_now(); }

 private:
  static std::string log_path(const std::string& name) {
    const std::string dir = std::string(TIRSTRAIN_TEST_TMP) + "/capture_aravis";
    std::filesystem::create_directories(dir);
    return dir + "/" + name + ".camera.log";
  }
  static std::vector<std::string> make_args(int lost) {
    std::vector<std::string> args = {"arv-fake-gv-camera-0.8", "-i", "127.0.0.1"};
    if (lost > 0) {
      args.push_back("-r");
      args.push_back(std::to_string(lost));
    }
    return args;
  }
  Child child_;
};

}  // namespace tirstrain::testing
