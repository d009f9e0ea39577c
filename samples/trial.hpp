#pragma once
// A synthetic TIR trial: load history, deformation field, textures, contact geometry, sensor and channels,
// all derived from one SynthConfig and one seed. Rendering is pure (const, no I/O) so tests can render in
// memory; write_trial (samples/synth.hpp) puts a trial on disk.
#include <opencv2/core.hpp>

#include <vector>

#include "samples/field.hpp"
#include "samples/synth_config.hpp"
#include "samples/texture.hpp"

namespace tirstrain::samples {

struct ChannelSeries {
  std::vector<double> t_s, normal_N, tangential_N, plate_x_mm, plate_y_mm, accel_m_s2;
  std::vector<double> pad_force_N;  // force driving the pad model (Q + slip fluctuation), not written to disk
};

// Truth on the regular grid of reference points for one frame, row-major [ny][nx].
struct GridTruth {
  std::vector<double> displacement_px;   // [ny][nx][2]
  std::vector<double> gradient;          // [ny][nx][4]: H_xx, H_xy, H_yx, H_yy
  std::vector<double> strain;            // [ny][nx][3]: E_xx, E_yy, E_xy (Green–Lagrange, tensor shear)
  std::vector<double> energy_J_m3;       // [ny][nx]: plane-strain energy density
  std::vector<std::uint8_t> in_contact;  // [ny][nx]: current position X + u inside the contact mask
  std::vector<std::uint8_t> in_stick;    // [ny][nx]: inside the stick zone (|X_model| < c) and in contact
};

class Trial {
 public:
  // Validates what parsing alone cannot (the contact model's parameters); throws Error naming the key.
  explicit Trial(SynthConfig config);

  const SynthConfig& config() const { return config_; }
  const LoadHistory& history() const { return history_; }
  int frames() const { return config_.timing.frames; }
  int width() const { return config_.image.width_px; }
  int height() const { return config_.image.height_px; }
  const std::vector<double>& frame_times_s() const { return frame_times_s_; }
  LoadState load(int frame) const { return history_.at(frame_times_s_.at(static_cast<std::size_t>(frame))); }
  FrameField field(int frame) const { return history_.field_at(load(frame)); }

  // Noise-free image of a frame, full scale 1 (CV_32F); a frame listed for motion blur is averaged over
  // its exposure.
  cv::Mat render_clean(int frame) const;
  // Noise-free instantaneous image at any time.
  cv::Mat render_clean_at(double t_s) const;
  // Blur, gain, shot and read noise, saturation and quantisation to the scene's bit depth (CV_8U/CV_16U).
  cv::Mat apply_sensor(const cv::Mat& clean, int frame) const;
  // The reference position of every pixel's centre in a frame (CV_64FC2, x then y) and the largest forward
  // residual |X + u(X) - x| over the image.
  cv::Mat inverse_map(int frame, double* max_residual_px) const;

  // Contact geometry (fixed in the image: the finger does not move, the skin deforms inside the contact).
  double contact_signed_distance_px(Vec2 x) const;  // < 0 inside
  double contact_weight(Vec2 x) const;              // soft edge, 0.5 on the border
  // The two factors of the ridge contrast at a signed distance from the border (px, < 0 inside): the soft
  // edge (0.5 on the border) and the fade of contrast towards the border (fade_floor there, 1 deep inside).
  double edge_weight(double signed_distance_px) const;
  double border_fade(double signed_distance_px) const;
  double background_level() const { return background_; }  // optics background, fraction of full scale
  bool in_contact(Vec2 x) const { return contact_signed_distance_px(x) <= 0.0; }
  cv::Mat contact_mask() const;  // CV_8U, 1 inside

  // Regular grid of reference points covering the image.
  const std::vector<double>& grid_x_px() const { return grid_x_px_; }
  const std::vector<double>& grid_y_px() const { return grid_y_px_; }
  GridTruth grid_truth(int frame) const;

  // Ridge direction in the image at image position x for a frame's field (from +x towards +y, in [0, pi)):
  // the fingerprint's direction t at the reference point X with X + u(X) = x, carried into the image by
  // F = I + H(X) (a material line element dX maps to F dX).
  double ridge_orientation_rad(const FrameField& field, Vec2 x_px) const;
  // Ridge orientation averaged over square blocks of the image, indexed as contact/'s orientation blocks:
  // block (i, j) holds the pixels x in [i b, (i + 1) b), y in [j b, (j + 1) b), the last row and column
  // clipped to the image. Each value is the doubled-angle mean over an 8 x 8 lattice of sub-cell centres;
  // coherence is the length of that mean (1: one direction across the block; low around the core, a delta
  // or a minutia, where the block mean says little). CV_64F, rows = blocks down.
  struct OrientationBlocks {
    cv::Mat orientation_rad;
    cv::Mat coherence;
  };
  OrientationBlocks ridge_orientation_blocks(int frame, int block_px) const;

  ChannelSeries channels() const;

  const Fingerprint& fingerprint() const { return fingerprint_; }

 private:
  void render_into(const LoadState& state, cv::Mat& out) const;
  double illumination(Vec2 x, double t_s) const;

  SynthConfig config_;
  LoadHistory history_;
  std::vector<double> frame_times_s_;
  Fingerprint fingerprint_;
  PlatePattern pattern_;
  SweatBlobs sweat_;
  double border_coeff_[4] = {};  // radius modulation cos(k theta + phase), k = 2..5
  double border_phase_[4] = {};
  double background_ = 0.8;
  std::vector<double> grid_x_px_, grid_y_px_;
  cv::Mat signed_distance_px_;  // contact_signed_distance_px at every pixel centre (the contact is fixed)
};

}  // namespace tirstrain::samples
