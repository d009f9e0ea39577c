// `tirstrain cameras`: what each camera backend can see, with the URI to pass to record/live.
#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "capture/aravis_source.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {
namespace {

// V4L2 capture nodes, asked directly: a /dev/videoN that cannot capture (metadata, output) is left out.
std::vector<capture::CameraInfo> list_v4l2_devices() {
  std::vector<capture::CameraInfo> out;
  std::vector<std::string> nodes;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("video", 0) == 0) nodes.push_back(entry.path().string());
  }
  std::sort(nodes.begin(), nodes.end());
  for (const auto& node : nodes) {
    const int fd = ::open(node.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) continue;
    v4l2_capability caps{};
    const bool ok = ::ioctl(fd, VIDIOC_QUERYCAP, &caps) == 0;
    ::close(fd);
    if (!ok) continue;
    const unsigned device_caps =
        (caps.capabilities & V4L2_CAP_DEVICE_CAPS) ? caps.device_caps : caps.capabilities;
    if (!(device_caps & V4L2_CAP_VIDEO_CAPTURE)) continue;
    capture::CameraInfo info;
    info.backend = "v4l2";
    info.uri = "v4l2:" + node;
    info.model = reinterpret_cast<const char*>(caps.card);
    info.address = reinterpret_cast<const char*>(caps.bus_info);
    info.protocol = reinterpret_cast<const char*>(caps.driver);
    out.push_back(info);
  }
  return out;
}

}  // namespace

void add_cameras_command(CLI::App& app) {
  struct Args {
    std::string backend = "all";
  };
  auto args = std::make_shared<Args>();
  CLI::App* sub = app.add_subcommand(
      "cameras",
      "List connected cameras per backend with the URI to use in 'record' and 'live'.\n"
      "Aravis (GigE Vision / USB3 Vision) discovery broadcasts on every network interface and takes ~1 s.");
  sub->add_option("--backend", args->backend, "aravis, v4l2, libcamera or all (default)")
      ->check(CLI::IsMember({"aravis", "v4l2", "libcamera", "all"}));
  sub->callback([args] {
    auto print = [](const std::string& backend, const std::vector<capture::CameraInfo>& cameras,
                    const std::string& note) {
      std::cout << backend << ": " << cameras.size() << " camera" << (cameras.size() == 1 ? "" : "s") << note
                << "\n";
      for (const auto& c : cameras) {
        std::cout << "  " << c.uri << "  " << c.model;
        if (!c.serial.empty()) std::cout << "  serial " << c.serial;
        if (!c.address.empty()) std::cout << "  at " << c.address;
        if (!c.protocol.empty()) std::cout << "  (" << c.protocol << ")";
        std::cout << "\n";
      }
    };
    const bool all = args->backend == "all";
    if (all || args->backend == "aravis") print("aravis", capture::list_aravis_cameras(), "");
    if (all || args->backend == "v4l2")
      print("v4l2", list_v4l2_devices(), " (capture backend not built yet)");
    if (all || args->backend == "libcamera") print("libcamera", {}, " (backend not built yet; not searched)");
  });
}

}  // namespace tirstrain::cli
