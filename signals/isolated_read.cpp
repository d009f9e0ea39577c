#include "signals/isolated_read.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

// How the child ended, for the message.
std::string how_it_ended(int status) {
  if (WIFSIGNALED(status)) {
    const int signal = WTERMSIG(status);
    const char* name = strsignal(signal);
    return "crashed (signal " + std::to_string(signal) + (name ? std::string(", ") + name : "") + ")";
  }
  return "stopped with exit status " + std::to_string(WEXITSTATUS(status));
}

}  // namespace

void survive_read_in_child(const std::string& path, const std::string& library,
                           const std::function<void()>& read) {
  const pid_t child = fork();
  if (child < 0) return;  // no process to spare: the read happens in this one, unguarded
  if (child == 0) {
    // The child's only job is to survive the read: whatever it throws, the parent reports when it reads.
    try {
      read();
    } catch (...) {
    }
    _exit(0);  // no atexit handlers, no flushing of the parent's buffers
  }
  int status = 0;
  while (waitpid(child, &status, 0) < 0)
    if (errno != EINTR) return;
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return;
  throw Error(library + " " + how_it_ended(status) +
                  " reading this file in a separate process: the file is damaged in a way not checked "
                  "before reading, and is not read here (it was not changed)",
              {.file = path});
}

}  // namespace tirstrain::signals
