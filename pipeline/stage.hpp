#pragma once
// The pipeline's plug-in point. Each analysis the scene's `compute` list can ask for (contact, tracking,
// strain, channels) is a Stage: it sees every frame in order, keeps what it measures, and at the end writes
// its own group of result.h5 (/contact, /tracks, /mesh, /strain, /energy, /channels), its columns of
// frames.csv and its part of summary.json. Per-frame arrays (tracks, strains, maps) are written to result.h5
// as each frame is done (TrialInfo::out) and not kept, so memory does not grow with the trial's length
// beyond a few scalars per frame (for frames.csv and summary.json). Stages later in the list read the results
// of earlier ones from the FrameContext (tracking needs the contact ROI, strain needs tracks).
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame_source.hpp"
#include "contact/segmenter.hpp"
#include "core/archive.hpp"
#include "core/h5_stream.hpp"
#include "core/overlay_text.hpp"
#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "flow/tracker.hpp"

namespace tirstrain::pipeline {

struct TrialInfo {
  cv::Size frame_size;  // of the first decodable frame; every usable frame has it
  int depth = CV_8U;    // CV_8U or CV_16U
  std::int64_t expected_frames = -1;
  const Scene* scene = nullptr;
  // false in the live view: stages keep only the newest frame's record (enough to draw), so memory stays
  // flat however long the view runs; write() and csv_row() are then not called.
  bool keep_history = true;
  // Where per-frame rows are written as frames are done (result row = frame's row in /frames); null when
  // nothing is written (the live view).
  H5Stream* out = nullptr;
};

// Appends a frame's record, or keeps only the newest one when the trial keeps no history.
template <typename Record>
void remember(std::vector<Record>& records, Record&& record, bool keep_history) {
  if (!keep_history) records.clear();
  records.push_back(std::move(record));
}

// What one frame carries through the stages.
struct FrameContext {
  const capture::Frame* frame = nullptr;
  bool usable = false;  // false: corrupt / undecodable frame; stages record a placeholder
  std::optional<contact::ContactResult> contact;  // filled by the contact stage
  // Filled by the tracking stage once it has started (the first frame with contact is its reference).
  struct Tracking {
    const std::vector<flow::Track>* tracks = nullptr;  // every track ever created; index == id
    int frame = 0;                                     // tracker frame: 0 is the reference frame
    bool reference_frame = false;                      // this frame is the tracker's reference frame
    // The contact's standard-ellipse normalisation of the reference frame (identity without an ellipse).
    const contact::EllipseNormalization* reference_normalization = nullptr;
    bool reference_has_ellipse = false;
  };
  std::optional<Tracking> tracking;
  // Filled by the tracking stage: plate displacement since the first frame (absent without a pattern band).
  std::optional<Vec2> plate_displacement_px;
  // Filled by the strain stage: total strain energy U of this frame (J), absent when not computable.
  std::optional<double> strain_energy_J;
};

class Stage {
 public:
  virtual ~Stage() = default;
  virtual std::string name() const = 0;
  // Called once, before the first usable frame; unusable frames before it still reach process().
  virtual void start(const TrialInfo& info) = 0;
  // Every frame, in order, usable or not, so per-frame datasets stay aligned with /frames.
  virtual void process(FrameContext& context) = 0;
  // Draws this stage's result for people to look at (BGR 8-bit frame); its status line goes through `text`
  // (sized to the frame, on a backdrop, away from the pattern band).
  virtual void draw(cv::Mat& /*bgr*/, const FrameContext& /*context*/, const OverlayText& /*text*/) const {}
  // Per-frame columns appended to frames.csv, and the row for frame `row` (0-based, in processing order).
  virtual std::vector<std::string> csv_header() const { return {}; }
  virtual void csv_row(std::size_t /*row*/, std::vector<std::string>& /*cells*/) const {}
  // After the last frame, before anything is written. A stage that revises its per-frame results now, with
  // the whole trial in hand (the tracking stage smooths its tracks in time), returns true: the stages after
  // it are then made afresh and run over contexts from replay(), so that what they derive follows the
  // revision (the overlay, drawn while the frames were read, is not redrawn); their rows are written again.
  virtual bool finish() { return false; }
  // Puts into `context` what process() put there for result row `row`, as revised by finish(): what later
  // stages read (tracks, plate). Called only on a stage whose finish() returned true, or one before it.
  virtual void replay(FrameContext& /*context*/, std::size_t /*row*/) {}
  // After finish(): what is not per-frame (reference positions, the mesh, attributes) and what needs the
  // whole trial's scalars (rates by central differences). Per-frame rows are already in `out`.
  virtual void write(H5Stream& out) const = 0;
  virtual void summarize(nlohmann::json& /*summary*/) const {}
  // After finish(): what a user must read about this stage's results (each also in the stage's own part of
  // summary.json); the run prints them and lists them in summary.json's `warnings`.
  virtual std::vector<std::string> warnings() const { return {}; }
  // Everything process() carries from frame to frame, in a checkpoint (core/archive.hpp), so that an
  // interrupted run continues where it stopped: written after start() and a number of frames, read back
  // into a stage made from the same scene and started on the same trial. What start() sets is not in it.
  virtual void archive(Archive& a) = 0;
};

// How a stage is made, and which stages it needs before it.
struct StageSpec {
  std::string name;
  std::vector<std::string> needs;
  // Null while the stage is not implemented in this build.
  std::function<std::unique_ptr<Stage>(const Scene&)> make;
};

// Every stage the scene may name, in pipeline order.
const std::vector<StageSpec>& stage_registry();

struct StagePlan {
  std::vector<std::unique_ptr<Stage>> stages;  // in pipeline order, dependencies included
  std::vector<std::string> unavailable;        // requested (or needed) but not built yet
};

// The stages the scene asks for plus what they need, and nothing else.
StagePlan plan_stages(const Scene& scene);

}  // namespace tirstrain::pipeline
