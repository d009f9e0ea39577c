// V4L2 and libcamera backends on a host without cameras: sequence-gap accounting, URI parsing, and the
// errors a user sees for a wrong device. Capture itself is tested against real drivers in tests/vm.
#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <string>

#include "capture/frame_source.hpp"
#include "capture/v4l2_source.hpp"
#include "core/error.hpp"

namespace tc = tirstrain::capture;

namespace {

std::string error_of(const std::string& uri, const tc::CameraSettings& settings = {}) {
  try {
    tc::open_source(uri, settings);
  } catch (const tirstrain::Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(SequenceGapCounter, ConsecutiveSequencesLoseNothing) {
  tc::SequenceGapCounter c;
  for (std::uint32_t s = 100; s < 110; ++s) {
    const auto step = c.add(s);
    EXPECT_EQ(step.frame_id, s);
    EXPECT_EQ(step.lost_before, 0);
  }
  EXPECT_EQ(c.lost(), 0);
  EXPECT_EQ(c.frames(), 10);
}

TEST(SequenceGapCounter, JumpsCountTheFramesInBetween) {
  tc::SequenceGapCounter c;
  EXPECT_EQ(c.add(0).lost_before, 0);
  EXPECT_EQ(c.add(1).lost_before, 0);
  EXPECT_EQ(c.add(4).lost_before, 2);  // 2 and 3 missing
  EXPECT_EQ(c.add(5).lost_before, 0);
  EXPECT_EQ(c.add(15).lost_before, 9);
  EXPECT_EQ(c.lost(), 11);
  // Books balance: span of ids = received + lost.
  EXPECT_EQ(15 - 0 + 1, c.frames() + c.lost());
}

TEST(SequenceGapCounter, UnwrapsThe32BitCounter) {
  tc::SequenceGapCounter c;
  c.add(0xFFFFFFFEu);
  const auto a = c.add(0xFFFFFFFFu);
  const auto b = c.add(1u);  // 0 was lost across the wrap
  EXPECT_EQ(a.frame_id, 0xFFFFFFFFll);
  EXPECT_EQ(b.frame_id, 0x100000001ll);
  EXPECT_EQ(b.lost_before, 1);
  EXPECT_EQ(c.lost(), 1);
}

TEST(SequenceGapCounter, ALateFrameTakesItselfBackOutOfTheLostCount) {
  tc::SequenceGapCounter c;
  c.add(10);
  EXPECT_EQ(c.add(13).lost_before, 2);  // 11, 12 missing
  const auto late = c.add(11);          // 11 arrives after all
  EXPECT_EQ(late.frame_id, 11);
  EXPECT_EQ(late.lost_before, -1);
  EXPECT_EQ(c.lost(), 1);
  EXPECT_EQ(c.add(14).lost_before, 0);  // counting goes on from the newest frame
  EXPECT_EQ(c.add(14).lost_before, 0);  // a repeated sequence is neither lost nor late
}

TEST(V4l2Uri, DevicePathsAndNumbers) {
  EXPECT_EQ(tc::v4l2_device_path("/dev/video3"), "/dev/video3");
  EXPECT_EQ(tc::v4l2_device_path("12"), "/dev/video12");
  EXPECT_THROW(tc::v4l2_device_path(""), tirstrain::Error);
  EXPECT_THROW(tc::v4l2_device_path("video0"), tirstrain::Error);
}

TEST(V4l2Formats, NamesAndFourccs) {
  EXPECT_EQ(tc::v4l2_fourcc_of("GREY", "--pixel-format"), V4L2_PIX_FMT_GREY);
  EXPECT_EQ(tc::v4l2_fourcc_of("Mono8", "--pixel-format"), V4L2_PIX_FMT_GREY);
  EXPECT_EQ(tc::v4l2_fourcc_of("Mono16", "--pixel-format"), V4L2_PIX_FMT_Y16);
  EXPECT_EQ(tc::v4l2_fourcc_of("YUYV", "--pixel-format"), V4L2_PIX_FMT_YUYV);
  EXPECT_EQ(tc::fourcc_to_string(V4L2_PIX_FMT_Y16), "Y16");
  EXPECT_EQ(tc::fourcc_to_string(V4L2_PIX_FMT_YUYV), "YUYV");
  try {
    tc::v4l2_fourcc_of("BayerRG8", "--pixel-format");
    FAIL() << "no error";
  } catch (const tirstrain::Error& e) {
    EXPECT_EQ(e.context().key, "--pixel-format");
    EXPECT_NE(std::string(e.what()).find("choices: GREY"), std::string::npos) << e.what();
  }
}

TEST(V4l2Errors, AMissingDeviceNodeSaysSoWithTheUri) {
  const std::string message = error_of("v4l2:/dev/video97");
  EXPECT_NE(message.find("v4l2:/dev/video97"), std::string::npos) << message;
  EXPECT_NE(message.find("No such file or directory"), std::string::npos) << message;
  EXPECT_NE(message.find("tirstrain cameras --backend v4l2"), std::string::npos) << message;
  EXPECT_NE(error_of("v4l2:97").find("/dev/video97"), std::string::npos);
}

TEST(V4l2Errors, ANodeThatIsNotV4l2IsRejected) {
  const std::string message = error_of("v4l2:/dev/null");
  EXPECT_NE(message.find("/dev/null is not a V4L2 device"), std::string::npos) << message;
}

TEST(LibcameraErrors, NoCameraOrNoMatchIsAClearError) {
  // This host has no libcamera camera (the VM tests have vimc).
  const std::string message = error_of("libcamera:Sensor Z");
  EXPECT_NE(message.find("libcamera:Sensor Z"), std::string::npos) << message;
  EXPECT_TRUE(message.find("finds no camera") != std::string::npos ||
              message.find("no libcamera camera matches 'Sensor Z'") != std::string::npos)
      << message;
}

TEST(CameraSettingsForFiles, StillRejectedWithTheCameraSchemesNamed) {
  tc::CameraSettings settings;
  settings.frame_rate_hz = 30.0;
  const std::string message = error_of("/nonexistent/frames", settings);
  EXPECT_NE(message.find("v4l2:/dev/videoN"), std::string::npos) << message;
}
