// Entry point of the Aravis tests. Camera traffic must never leave a private network namespace that has
// only a loopback interface: on the host network the fake camera also answers on (and broadcasts to) the
// machine's real interfaces. So this binary re-executes itself as
//   unshare -n -m sh -c 'ip link set lo up && exec BINARY ARGS...'
// before running any test, and refuses to run tests if, once inside, it sees any interface but "lo".
// -m (a private mount namespace) lets the disk-full test mount a small tmpfs that nobody else sees.
// Listing tests (gtest_discover_tests at build time) sends no traffic and runs without the namespace.
#include <gtest/gtest.h>
#include <net/if.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "tests/capture_aravis/netns.hpp"

namespace tirstrain::testing {

std::string& namespace_problem() {
  static std::string problem;
  return problem;
}

}  // namespace tirstrain::testing

namespace {

constexpr const char* kInsideVar = "TIRSTRAIN_ARAVIS_TEST_NETNS";

std::vector<std::string> interface_names() {
  std::vector<std::string> names;
  // `struct` is needed: the function if_nameindex() hides the type name.
  if (struct if_nameindex* list = if_nameindex()) {
    for (struct if_nameindex* i = list; i->if_index != 0; ++i) names.emplace_back(i->if_name);
    if_freenameindex(list);
  }
  return names;
}

}  // namespace

int main(int argc, char** argv) {
  bool listing = false;
  for (int i = 1; i < argc; ++i)
    if (std::strncmp(argv[i], "--gtest_list_tests", 18) == 0) listing = true;

  std::string& problem = tirstrain::testing::namespace_problem();
  if (!listing && std::getenv(kInsideVar) == nullptr) {
    // Probe first: if unshare cannot create the namespaces (not root, no unshare), tests skip rather than
    // fail, and nothing is ever sent on the host network.
    if (std::system("unshare -n -m true >/dev/null 2>&1") == 0) {
      setenv(kInsideVar, "1", 1);
      // glib and aravis keep process-lifetime allocations (type system, interface lists) that LSan reports.
      const std::string supp = std::string(TIRSTRAIN_SOURCE_DIR) + "/tests/capture_aravis/lsan.supp";
      setenv("LSAN_OPTIONS", ("suppressions=" + supp + ":print_suppressions=0").c_str(), 1);
      std::vector<const char*> args = {
          "unshare", "-n", "-m",
          "sh",      "-c", "PATH=$PATH:/usr/sbin:/sbin; ip link set lo up && exec \"$0\" \"$@\""};
      for (int i = 0; i < argc; ++i) args.push_back(argv[i]);
      args.push_back(nullptr);
      execvp("unshare", const_cast<char* const*>(args.data()));
      problem = std::string("cannot run unshare: ") + std::strerror(errno);
    } else {
      problem =
          "'unshare -n -m' is unavailable (needs root or CAP_SYS_ADMIN); camera tests are skipped so that "
          "no camera traffic touches the host network";
    }
  }
  if (!listing && problem.empty()) {
    for (const std::string& name : interface_names()) {
      if (name != "lo") {
        std::fprintf(stderr,
                     "refusing to run camera tests: network interface '%s' is visible (expected only lo)\n",
                     name.c_str());
        return 2;
      }
    }
  }
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
