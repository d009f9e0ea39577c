// A fast GigE Vision fake camera for benchmarks: Aravis' ArvGvFakeCamera (real GVCP/GVSP, as
// arv-fake-gv-camera-0.8) with a fill-pattern callback that copies pre-rendered TIR-like frames instead of
// rendering every pixel in double precision, which caps arv-fake-gv-camera-0.8 at ~180 frames/s at
// 1280x1024. Frame timing, frame ids, ROI, pixel format, packet size, frame rate and trigger are Aravis'
// own fake camera's; only the pixel source differs.
//
//   tirstrain_fake_camera [--address 127.0.0.1] [--serial FAST01] [--frames K | --images DIR]
//
// Serves until SIGINT/SIGTERM, then prints how many frames it generated. Run it ONLY inside a private
// loopback-only network namespace (bench/capture_record_bench.sh does): on the host network Aravis' fake
// camera also answers on the machine's real interfaces.
//
// Mono8 frames (and Bayer 8-bit) are one memcpy per ROI row from a pre-rendered 2048x2048 frame (one of K,
// cycling); Mono16 frames are the same values times 257. The first two pixels of each Mono8 frame carry the
// 16-bit frame id (big-endian) so a recording can be checked against what was sent. With --images DIR the
// frames are instead the images in DIR (e.g. a `tirstrain synth` trial's frames/, in name order, cycling),
// each at the sensor's top-left corner and unmarked: ROI 0,0,W,H serves them exactly.
#include <arv.h>
#include <signal.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace {

constexpr int kSensor = 2048;  // ARV_FAKE_CAMERA_SENSOR_WIDTH/HEIGHT

// Ridges at ~9 px period inside an elliptical contact plus sensor noise; `phase` shifts the ridges so that
// consecutive frames differ.
cv::Mat tir_frame(int phase, cv::RNG& rng) {
  cv::Mat image(kSensor, kSensor, CV_8UC1);
  for (int y = 0; y < image.rows; ++y) {
    auto* row = image.ptr<std::uint8_t>(y);
    for (int x = 0; x < image.cols; ++x) {
      const double dx = (x - 640) / 420.0, dy = (y - 512) / 330.0;
      const double inside = dx * dx + dy * dy < 1 ? 1.0 : 0.15;
      const double ridge =
          0.5 + 0.5 * std::sin(2 * M_PI * (x * 0.8 + y * 0.6 + 6 * std::sin(y / 90.0) + phase) / 9.0);
      const double value = 30 + 180 * inside * ridge + rng.gaussian(4.0);
      row[x] = static_cast<std::uint8_t>(std::clamp(value, 0.0, 255.0));
    }
  }
  return image;
}

struct Frames {
  std::vector<cv::Mat> images;
  std::atomic<std::uint64_t> served{0};
  bool mark_ids = true;
};

// The images of a folder, in name order, each on a black 2048x2048 canvas at the top-left corner.
std::vector<cv::Mat> load_images(const std::string& dir) {
  std::vector<std::string> paths;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    const std::string ext = entry.path().extension().string();
    if (ext == ".png" || ext == ".tif" || ext == ".tiff" || ext == ".pgm")
      paths.push_back(entry.path().string());
  }
  std::sort(paths.begin(), paths.end());
  std::vector<cv::Mat> images;
  for (const auto& path : paths) {
    cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (image.empty() || image.cols > kSensor || image.rows > kSensor) {
      std::fprintf(stderr, "cannot use %s (unreadable or larger than %dx%d)\n", path.c_str(), kSensor,
                   kSensor);
      return {};
    }
    cv::Mat canvas(kSensor, kSensor, CV_8UC1, cv::Scalar(0));
    image.copyTo(canvas(cv::Rect(0, 0, image.cols, image.rows)));
    images.push_back(canvas);
  }
  return images;
}

void fill(ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat format) {
  auto* frames = static_cast<Frames*>(data);
  size_t size = 0;
  auto* out = static_cast<unsigned char*>(const_cast<void*>(arv_buffer_get_data(buffer, &size)));
  gint x = 0, y = 0, width = 0, height = 0;
  arv_buffer_get_image_region(buffer, &x, &y, &width, &height);
  const cv::Mat& source = frames->images[frames->served.fetch_add(1) % frames->images.size()];
  const int bytes_per_pixel = ARV_PIXEL_FORMAT_BIT_PER_PIXEL(format) / 8;
  const std::size_t row_bytes = static_cast<std::size_t>(width) * bytes_per_pixel;
  // arv_fake_camera_fill_buffer() calls us only when the buffer holds the whole payload (width x height x
  // bytes per pixel); `size` is the buffer's received size, still 0 here, so it is no bound.
  (void)size;
  if (x < 0 || y < 0 || x + width > kSensor || y + height > kSensor || bytes_per_pixel < 1 ||
      bytes_per_pixel > 2)
    return;  // the fake camera refuses such a region already
  for (int r = 0; r < height; ++r) {
    const std::uint8_t* src = source.ptr<std::uint8_t>(y + r) + x;
    unsigned char* dst = out + r * row_bytes;
    if (bytes_per_pixel == 1) {
      std::memcpy(dst, src, row_bytes);
    } else {
      auto* dst16 = reinterpret_cast<std::uint16_t*>(dst);
      for (int c = 0; c < width; ++c) dst16[c] = static_cast<std::uint16_t>(src[c] * 257);
    }
  }
  if (frames->mark_ids && bytes_per_pixel == 1 && width >= 2) {
    const std::uint64_t id = arv_buffer_get_frame_id(buffer);
    out[0] = static_cast<unsigned char>((id >> 8) & 0xff);
    out[1] = static_cast<unsigned char>(id & 0xff);
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string address = "127.0.0.1", serial = "FAST01", images_dir;
  int count = 8;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--address" && i + 1 < argc) {
      address = argv[++i];
    } else if (arg == "--serial" && i + 1 < argc) {
      serial = argv[++i];
    } else if (arg == "--frames" && i + 1 < argc) {
      count = std::atoi(argv[++i]);
    } else if (arg == "--images" && i + 1 < argc) {
      images_dir = argv[++i];
    } else {
      std::fprintf(stderr, "usage: %s [--address 127.0.0.1] [--serial FAST01] [--frames K | --images DIR]\n",
                   argv[0]);
      return 2;
    }
  }
  if (count < 1 || count > 64) {
    std::fprintf(stderr, "--frames must be 1..64\n");
    return 2;
  }
  // Block the stop signals before Aravis starts its thread, so only sigwait() below sees them.
  sigset_t stop;
  sigemptyset(&stop);
  sigaddset(&stop, SIGINT);
  sigaddset(&stop, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop, nullptr);

  Frames frames;
  if (!images_dir.empty()) {
    frames.images = load_images(images_dir);
    frames.mark_ids = false;
    if (frames.images.empty()) {
      std::fprintf(stderr, "no usable images in %s\n", images_dir.c_str());
      return 1;
    }
    count = static_cast<int>(frames.images.size());
  } else {
    cv::RNG rng(12345);
    for (int i = 0; i < count; ++i) frames.images.push_back(tir_frame(i, rng));
  }

  ArvGvFakeCamera* camera = arv_gv_fake_camera_new(address.c_str(), serial.c_str());
  if (camera == nullptr || !arv_gv_fake_camera_is_running(camera)) {
    std::fprintf(stderr, "cannot start the fake camera on %s\n", address.c_str());
    if (camera != nullptr) g_object_unref(camera);
    return 1;
  }
  arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(camera), fill, &frames);
  std::fprintf(stderr, "tirstrain_fake_camera: serving %d %s frames on %s (serial %s)\n", count,
               images_dir.empty() ? "pre-rendered" : "loaded", address.c_str(), serial.c_str());
  int signal_number = 0;
  sigwait(&stop, &signal_number);
  g_object_unref(camera);
  std::fprintf(stderr, "tirstrain_fake_camera: %llu frames generated\n",
               static_cast<unsigned long long>(frames.served.load()));
  return 0;
}
