// `tirstrain cameras`: what each camera backend can see, with the URI to pass to record/live.
#include <iostream>
#include <string>
#include <vector>

#include "capture/aravis_source.hpp"
#include "capture/libcamera_source.hpp"
#include "capture/v4l2_source.hpp"
#include "core/error.hpp"
#include "tirstrain/commands.hpp"

namespace tirstrain::cli {

void add_cameras_command(CLI::App& app) {
  struct Args {
    std::string backend = "all";
  };
  auto args = std::make_shared<Args>();
  CLI::App* sub = app.add_subcommand(
      "cameras",
      "List connected cameras per backend with the URI to use in 'record' and 'live'.\n"
      "Aravis (GigE Vision / USB3 Vision) discovery broadcasts on every network interface and takes ~1 s.");
  sub->footer("Example:\n  tirstrain cameras --backend aravis");
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
    if (all || args->backend == "v4l2") print("v4l2", capture::list_v4l2_cameras(), "");
    if (all || args->backend == "libcamera") {
      // libcamera also sees V4L2 sensors behind a media controller (vimc, CSI cameras) that v4l2: cannot
      // drive directly; a camera manager that cannot start is reported, not fatal for the other backends.
      try {
        print("libcamera", capture::list_libcamera_cameras(), "");
      } catch (const Error& e) {
        print("libcamera", {}, std::string(" (") + e.message() + ")");
      }
    }
  });
}

}  // namespace tirstrain::cli
