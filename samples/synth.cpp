#include "samples/synth.hpp"

#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "core/atomic_output.hpp"
#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/progress.hpp"
#include "core/scene.hpp"

namespace tirstrain::samples {
namespace {

const char* field_name(FieldKind kind) {
  switch (kind) {
    case FieldKind::kCattaneoMindlin:
      return "cattaneo_mindlin";
    case FieldKind::kRigid:
      return "rigid";
    case FieldKind::kAffine:
      return "affine";
    case FieldKind::kNone:
      break;
  }
  return "none";
}

std::string frame_name(int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.png", index);
  return name;
}

// The scene written next to the frames: the input scene with the seed actually used, so the trial can be
// re-rendered bit for bit and `tirstrain process` finds calibration, tissue and the pattern band.
// The trial's scene as it is written beside the frames: the seed drawn made explicit.
Scene trial_scene(const Trial& trial) {
  Scene scene = trial.config().scene;
  scene.synthesis = scene.synthesis.with("seed", std::to_string(trial.config().seed));
  return scene;
}

void write_scene(const Trial& trial, const std::string& path) {
  save_scene(trial_scene(trial), path);
}

// What the truth describes: the trial's scene, tissue, loading and contact geometry.
void write_truth_attributes(const Trial& trial, H5Writer& out) {
  const SynthConfig& cfg = trial.config();
  const LoadHistory& history = trial.history();
  out.attribute("/", "format", kTruthFormat);
  out.attribute("/", "version", kTruthVersion);
  out.attribute("/", "field", field_name(cfg.loading.field));
  out.attribute("/", "scene_file", cfg.scene.file);
  out.attribute("/", "scene_yaml", scene_to_yaml(trial_scene(trial)));  // what scene.yaml must still say
  out.attribute("/", "seed", static_cast<double>(cfg.seed));
  out.attribute("/", "px_per_mm", cfg.scene.px_per_mm);
  out.attribute("/", "width_px", static_cast<double>(trial.width()));
  out.attribute("/", "height_px", static_cast<double>(trial.height()));
  out.attribute("/", "ridge_period_mm", cfg.ridge_period_mm);
  out.attribute("/", "ridge_polarity", cfg.ridges_dark ? "dark" : "bright");
  out.attribute("/", "young_Pa", cfg.scene.tissue.young_Pa);
  out.attribute("/", "poisson", cfg.scene.tissue.poisson);
  out.attribute("/", "friction", cfg.loading.friction);
  out.attribute("/", "direction_rad", history.direction_rad());
  out.attribute("/", "contact_centre_x_px", history.contact_centre_px().x);
  out.attribute("/", "contact_centre_y_px", history.contact_centre_px().y);
  out.attribute("/", "contact_semi_axis_1_px", history.contact_semi_axes_px().x);
  out.attribute("/", "contact_semi_axis_2_px", history.contact_semi_axes_px().y);
  out.attribute("/", "contact_angle_rad", history.contact_angle_rad());
  out.attribute("/", "contact_radius_m", history.contact_radius_m());
  out.attribute("/", "max_rigid_shift_m", history.max_rigid_shift_m());
}

// Per frame: time, loads, stick radius, rigid shift, full slip and the plate's displacement.
void write_load_series(const Trial& trial, H5Writer& out) {
  const LoadHistory& history = trial.history();
  const auto frames = static_cast<std::size_t>(trial.frames());
  std::vector<double> t_s(frames), normal(frames), tangential(frames), stick(frames), shift(frames),
      plate(2 * frames);
  std::vector<std::uint8_t> slip(frames);
  for (std::size_t k = 0; k < frames; ++k) {
    const LoadState s = trial.load(static_cast<int>(k));
    const FrameField field = history.field_at(s);
    t_s[k] = s.t_s;
    normal[k] = s.normal_N;
    tangential[k] = s.tangential_N;
    stick[k] = field.model() ? field.model()->stick_radius_m() : s.stick_radius_m;
    shift[k] = field.model() ? field.model()->rigid_shift_m() : s.rigid_shift_m;
    plate[2 * k] = s.plate_px.x;
    plate[2 * k + 1] = s.plate_px.y;
    slip[k] = s.full_slip ? 1 : 0;
  }
  out.write("/frames/t_s", std::span<const double>(t_s), {frames});
  out.write("/load/normal_N", std::span<const double>(normal), {frames});
  out.write("/load/tangential_N", std::span<const double>(tangential), {frames});
  out.write("/load/stick_radius_m", std::span<const double>(stick), {frames});
  out.write("/load/rigid_shift_m", std::span<const double>(shift), {frames});
  out.write("/load/full_slip", std::span<const std::uint8_t>(slip), {frames});
  out.write("/plate/displacement_px", std::span<const double>(plate), {frames, 2});
}

// The exact field on the regular grid, every frame.
void write_grid_fields(const Trial& trial, const std::vector<GridTruth>& grid, H5Writer& out) {
  const auto frames = static_cast<std::size_t>(trial.frames());
  const std::size_t nx = trial.grid_x_px().size(), ny = trial.grid_y_px().size();
  out.write("/grid/x_px", std::span<const double>(trial.grid_x_px()), {nx});
  out.write("/grid/y_px", std::span<const double>(trial.grid_y_px()), {ny});
  const auto stack = [&](auto member, std::size_t components) {
    using T = typename std::remove_reference_t<decltype(grid.front().*member)>::value_type;
    std::vector<T> all;
    all.reserve(frames * ny * nx * components);
    for (const GridTruth& g : grid) all.insert(all.end(), (g.*member).begin(), (g.*member).end());
    return all;
  };
  const auto displacement = stack(&GridTruth::displacement_px, 2);
  out.write("/field/displacement_px", std::span<const double>(displacement), {frames, ny, nx, 2});
  const auto gradient = stack(&GridTruth::gradient, 4);
  out.write("/field/gradient", std::span<const double>(gradient), {frames, ny, nx, 4});
  const auto strain = stack(&GridTruth::strain, 3);
  out.write("/field/strain", std::span<const double>(strain), {frames, ny, nx, 3});
  const auto energy = stack(&GridTruth::energy_J_m3, 1);
  out.write("/field/energy_density_J_m3", std::span<const double>(energy), {frames, ny, nx});
  const auto contact = stack(&GridTruth::in_contact, 1);
  out.write("/field/in_contact", std::span<const std::uint8_t>(contact), {frames, ny, nx});
  const auto stick_flags = stack(&GridTruth::in_stick, 1);
  out.write("/field/in_stick", std::span<const std::uint8_t>(stick_flags), {frames, ny, nx});
  out.attribute("/field/gradient", "components", "H_xx, H_xy, H_yx, H_yy (H_ij = du_i/dX_j)");
  out.attribute("/field/strain", "components", "E_xx, E_yy, E_xy (Green-Lagrange, tensor shear)");
}

// The ridge orientation averaged over the contact segmenter's blocks, every frame.
void write_orientation(const Trial& trial, const std::vector<Trial::OrientationBlocks>& orientation,
                       H5Writer& out) {
  const auto frames = static_cast<std::size_t>(trial.frames());
  const auto blocks_y = static_cast<std::size_t>(orientation.front().orientation_rad.rows);
  const auto blocks_x = static_cast<std::size_t>(orientation.front().orientation_rad.cols);
  const auto stack_blocks = [&](cv::Mat Trial::OrientationBlocks::*member) {
    std::vector<double> all;
    all.reserve(frames * blocks_y * blocks_x);
    for (const Trial::OrientationBlocks& o : orientation)
      all.insert(all.end(), (o.*member).begin<double>(), (o.*member).end<double>());
    return all;
  };
  const auto angle = stack_blocks(&Trial::OrientationBlocks::orientation_rad);
  out.write("/texture/orientation_rad", std::span<const double>(angle), {frames, blocks_y, blocks_x});
  const auto coherence = stack_blocks(&Trial::OrientationBlocks::coherence);
  out.write("/texture/orientation_coherence", std::span<const double>(coherence),
            {frames, blocks_y, blocks_x});
  out.attribute("/texture/orientation_rad", "block_px",
                static_cast<double>(trial.config().truth.orientation_block_px));
}

void write_truth(const Trial& trial, const std::string& path, const std::vector<GridTruth>& grid,
                 const std::vector<cv::Mat>& masks,
                 const std::vector<Trial::OrientationBlocks>& orientation) {
  const auto frames = static_cast<std::size_t>(trial.frames());
  const auto w = static_cast<std::size_t>(trial.width()), h = static_cast<std::size_t>(trial.height());
  H5Writer out(path);
  write_truth_attributes(trial, out);
  write_load_series(trial, out);
  std::vector<std::uint8_t> mask_data;
  mask_data.reserve(frames * w * h);
  for (const cv::Mat& m : masks) mask_data.insert(mask_data.end(), m.datastart, m.dataend);
  out.write("/contact/mask", std::span<const std::uint8_t>(mask_data), {frames, h, w});
  write_grid_fields(trial, grid, out);
  write_orientation(trial, orientation, out);
  out.commit();
}

void write_channels(const Trial& trial, const std::string& path) {
  const ChannelSeries s = trial.channels();
  CsvWriter out(path, {"t_s", "normal_N", "tangential_N", "plate_x_mm", "plate_y_mm", "accel_m_s2"});
  for (std::size_t i = 0; i < s.t_s.size(); ++i)
    out.row({s.t_s[i], s.normal_N[i], s.tangential_N[i], s.plate_x_mm[i], s.plate_y_mm[i], s.accel_m_s2[i]});
  out.commit();
}

}  // namespace

void write_trial(const Trial& trial, const std::string& out_dir, bool quiet) {
  namespace fs = std::filesystem;
  StagingDirectory staging(out_dir);
  const fs::path root(staging.path());
  std::error_code ec;
  fs::create_directories(root / "frames", ec);
  if (ec) throw Error("cannot create directory: " + ec.message(), {.file = (root / "frames").string()});

  const cv::Mat mask = trial.contact_mask();
  std::vector<GridTruth> grid;
  std::vector<cv::Mat> masks;
  std::vector<Trial::OrientationBlocks> orientation;
  CsvWriter frames_csv((root / "frames.csv").string(), {"index", "t_s"});
  Progress progress("synth", trial.frames(), quiet);
  for (int k = 0; k < trial.frames(); ++k) {
    const cv::Mat image = trial.apply_sensor(trial.render_clean(k), k);
    const std::string file = (root / "frames" / frame_name(k)).string();
    if (!cv::imwrite(file, image)) {
      check_writable(root.string());        // names the cause when it is the disk
      check_complete_write(root.string());  // a disk nearly full still takes check_writable's small probe
      throw Error("cannot write image", {.file = file, .frame = k});
    }
    frames_csv.row_text(
        {std::to_string(k), format_double(trial.frame_times_s()[static_cast<std::size_t>(k)])});
    grid.push_back(trial.grid_truth(k));
    masks.push_back(mask);  // the contact is fixed in the image; stored per frame so consumers need not know
    orientation.push_back(trial.ridge_orientation_blocks(k, trial.config().truth.orientation_block_px));
    progress.update(k + 1);
  }
  progress.finish();
  frames_csv.commit();
  write_channels(trial, (root / "channels.csv").string());
  write_scene(trial, (root / "scene.yaml").string());
  write_truth(trial, (root / "truth.h5").string(), grid, masks, orientation);
  staging.commit();
}

SynthSummary synthesize(const SynthOptions& options) {
  if (options.out_dir.empty()) throw Error("an output directory is required", {.key = "--out"});
  // The output folder is replaced as a whole when complete, so it must not hold the scene it is made from.
  if (path_is_within(options.scene_path, options.out_dir))
    throw Error("the output folder holds the scene file " + options.scene_path +
                    "; it is replaced as a whole when the trial is complete, so give a folder of its own",
                {.file = options.out_dir, .key = "--out"});
  // Replacing the folder deletes what is in it: only an earlier trial's own files may be.
  check_replaceable_output(options.out_dir,
                           {"frames", "frames.csv", "channels.csv", "scene.yaml", "truth.h5"}, "synth");
  // Everything that can be wrong with the scene is found here, before the output directory exists.
  SynthConfig config = load_synth_config(options.scene_path);
  if (options.seed) config.seed = *options.seed;
  const Trial trial(std::move(config));
  const auto start = std::chrono::steady_clock::now();
  write_trial(trial, options.out_dir, options.quiet);
  SynthSummary summary;
  summary.frames = trial.frames();
  summary.render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summary.out_dir = options.out_dir;
  return summary;
}

}  // namespace tirstrain::samples
