#include "pipeline/channels_stage.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/yaml_reader.hpp"
#include "signals/channels.hpp"
#include "signals/friction.hpp"
#include "signals/friction_trial.hpp"
#include "signals/phases_json.hpp"

namespace tirstrain::pipeline {
namespace {

namespace ts = tirstrain::signals;
namespace fs = std::filesystem;

enum class Kind { kForce, kPosition, kAcceleration, kTrigger };

struct RoleSpec {
  const char* role;
  Kind kind;
};

// Every role a scene may map, in the order datasets and columns are written.
constexpr RoleSpec kRoles[] = {
    {"normal_force", Kind::kForce},
    {"tangential_force", Kind::kForce},
    {"tangential_force_x", Kind::kForce},
    {"tangential_force_y", Kind::kForce},
    {"plate_position", Kind::kPosition},
    {"plate_position_x", Kind::kPosition},
    {"plate_position_y", Kind::kPosition},
    {"accelerometer", Kind::kAcceleration},
    {"accelerometer_nail", Kind::kAcceleration},
    {"accelerometer_side", Kind::kAcceleration},
    {"trigger", Kind::kTrigger},
};

using Unit = ts::ColumnUnit;

ts::Quantity quantity_of(Kind kind) {
  switch (kind) {
    case Kind::kPosition:
      return ts::Quantity::kPosition;
    case Kind::kAcceleration:
      return ts::Quantity::kAcceleration;
    case Kind::kForce:
    case Kind::kTrigger:  // carries no unit; never asked for one
      break;
  }
  return ts::Quantity::kForce;
}

// Units a column name may end with ("_mm"), per kind; the first is the SI unit the stage writes.
std::vector<Unit> units_of(Kind kind) {
  return ts::column_units(quantity_of(kind));
}

std::string unit_list(Kind kind) {
  return ts::column_unit_list(quantity_of(kind));
}

struct Mapped {
  std::string role;
  std::string column;
  Kind kind = Kind::kForce;
  std::string unit;  // as recorded; "" for a trigger
  double to_si = 1.0;
  bool invert = false;
};

enum class Mode { kExplicit, kTrigger, kCrossCorrelation };

struct Config {
  std::string scene_file;
  std::string file;  // resolved against the scene file's folder
  ts::ChannelReadOptions read;
  std::vector<Mapped> mapped;
  Mode mode = Mode::kExplicit;
  double offset_s = 0.0;
  std::optional<double> threshold;
  bool rising = true;
  std::optional<double> camera_edge_s;
  double max_lag_s = 0.2;
  double min_normal_N = 0.05;
  ts::EventOptions events;

  const Mapped* find(const std::string& role) const {
    for (const auto& m : mapped)
      if (m.role == role) return &m;
    return nullptr;
  }
};

// How raw files are read: a sample rate for a file without time column, names for the columns of .mat
// matrices, and per-column calibration (raw DAQ volts -> the unit given under channels.units).
void parse_reading(YamlSection& top, const std::string& scene_file, ts::ChannelReadOptions& read) {
  if (top.has("rate_hz")) read.rate_Hz = top.number("rate_hz", 0.0, 1e-9, 1e12);
  if (top.has("mat_column_names")) {
    YamlSection matrices = top.section("mat_column_names");
    for (const std::string& matrix : matrices.keys())
      read.mat_column_names[matrix] = matrices.texts(matrix, {}, "column names, in column order");
    matrices.finish();
  }
  YamlSection calibration = top.section("calibration");
  if (top.has("calibration")) {
    for (const std::string& column : calibration.keys()) {
      YamlSection one = calibration.section(column);
      ts::ChannelCalibration cal;
      cal.gain = one.required_number("gain", -1e12, 1e12);
      cal.offset = one.number("offset", 0.0, -1e12, 1e12);
      if (cal.gain == 0.0)
        throw Error("a gain of 0 would erase the channel", {.file = scene_file, .key = one.path_of("gain")});
      one.finish();
      read.calibration[column] = cal;
    }
  }
  calibration.finish();
}

// The channel file (relative to the scene's folder) and how it is read.
void parse_file(YamlSection& top, const std::string& scene_file, Config& c) {
  const std::string file = top.required_text("file");
  if (file.empty()) throw Error("empty channel file name", {.file = scene_file, .key = "channels.file"});
  fs::path path(file);
  if (path.is_relative() && !scene_file.empty()) path = fs::path(scene_file).parent_path() / path;
  c.file = path.lexically_normal().string();
  c.read.time_column = top.text("time_column", "t_s");
  c.read.hdf5_group = top.text("hdf5_group", "/");
  c.read.rate_tolerance = top.number("rate_tolerance", 0.01, 0.0, 1.0);
  parse_reading(top, scene_file, c.read);
}

// A mapped column's unit: given under channels.units, else read from the column name's suffix (the
// longest that matches, so "_mm" is not read as "_m").
Unit unit_of_column(const RoleSpec& spec, const Mapped& m, YamlSection& columns, YamlSection& units,
                    const std::string& scene_file) {
  const std::string role = spec.role;
  const auto options = units_of(spec.kind);
  std::optional<Unit> unit;
  if (units.has(role)) {
    const std::string name = units.text(role, "");
    for (const Unit& u : options)
      if (name == u.name) unit = u;
    if (!unit)
      throw Error("unknown unit '" + name + "' (use one of " + unit_list(spec.kind) + ")",
                  {.file = scene_file, .key = units.path_of(role)});
    return *unit;
  }
  unit = ts::unit_of_column_name(m.column, quantity_of(spec.kind));
  if (!unit)
    throw Error("cannot tell the unit of column '" + m.column + "' from its name (expected a suffix _" +
                    unit_list(spec.kind) + "); give it under channels.units." + role,
                {.file = scene_file, .key = columns.path_of(role)});
  return *unit;
}

// channels.columns (role: column) and channels.units, every known role in turn.
void parse_columns(YamlSection& top, const std::string& scene_file, Config& c) {
  YamlSection columns = top.section("columns");
  YamlSection units = top.section("units");
  for (const RoleSpec& spec : kRoles) {
    const std::string role = spec.role;
    if (!columns.has(role)) {
      if (units.has(role))
        throw Error("a unit is given for role '" + role + "' but channels.columns does not map it",
                    {.file = scene_file, .key = units.path_of(role)});
      continue;
    }
    Mapped m;
    m.role = role;
    m.kind = spec.kind;
    m.column = columns.required_text(role);
    if (m.column.empty())
      throw Error("empty column name", {.file = scene_file, .key = columns.path_of(role)});
    if (spec.kind != Kind::kTrigger) {
      const Unit unit = unit_of_column(spec, m, columns, units, scene_file);
      m.unit = unit.name;
      m.to_si = unit.to_si;
    }
    c.mapped.push_back(m);
  }
  columns.finish();
  units.finish();
  if (c.mapped.empty())
    throw Error(
        "channels.columns maps no role (known: normal_force, tangential_force[_x/_y], "
        "plate_position[_x/_y], accelerometer, accelerometer_nail, accelerometer_side, trigger)",
        {.file = scene_file, .key = "channels.columns"});
}

// A one-axis role or both axes of it, never a mix; and no column mapped twice or to the time column.
void check_mapping(const std::string& scene_file, const Config& c) {
  for (const char* base : {"tangential_force", "plate_position"}) {
    const std::string b = base;
    const bool one = c.find(b) != nullptr, x = c.find(b + "_x") != nullptr, y = c.find(b + "_y") != nullptr;
    if (one && (x || y))
      throw Error("map either " + b + " or " + b + "_x and " + b + "_y, not both",
                  {.file = scene_file, .key = "channels.columns." + b});
    if (x != y)
      throw Error(b + "_x and " + b + "_y go together (one is missing)",
                  {.file = scene_file, .key = "channels.columns." + b + (x ? "_y" : "_x")});
  }
  std::vector<std::string> mapped_columns;
  for (const auto& m : c.mapped) {
    if (m.column == c.read.time_column)
      throw Error("role '" + m.role + "' is mapped to the time column",
                  {.file = scene_file, .key = "channels.columns." + m.role});
    if (std::find(mapped_columns.begin(), mapped_columns.end(), m.column) != mapped_columns.end())
      throw Error("column '" + m.column + "' is mapped to two roles",
                  {.file = scene_file, .key = "channels.columns." + m.role});
    mapped_columns.push_back(m.column);
  }
}

// channels.invert: the roles whose sign is flipped.
void parse_invert(YamlSection& top, const std::string& scene_file, Config& c) {
  if (!top.has("invert")) return;
  for (const std::string& role : top.texts("invert", {}, "roles whose sign is flipped")) {
    auto it = std::find_if(c.mapped.begin(), c.mapped.end(), [&](const Mapped& m) { return m.role == role; });
    if (it == c.mapped.end())
      throw Error("role '" + role + "' is not mapped under channels.columns",
                  {.file = scene_file, .key = "channels.invert"});
    it->invert = true;
  }
}

// channels.alignment: the mode and the keys that belong to it (a key of another mode is an error).
void parse_alignment(YamlSection& top, const std::string& scene_file, Config& c) {
  YamlSection align = top.section("alignment");
  const std::string mode = align.choice("mode", "explicit", {"explicit", "trigger", "cross_correlation"});
  const auto only_for = [&](const char* key, const char* for_mode) {
    if (align.has(key) && mode != for_mode)
      throw Error(std::string("applies to alignment mode '") + for_mode + "' only (mode is '" + mode + "')",
                  {.file = scene_file, .key = align.path_of(key)});
  };
  only_for("offset_s", "explicit");
  for (const char* key : {"threshold", "edge", "camera_edge_s"}) only_for(key, "trigger");
  only_for("max_lag_s", "cross_correlation");
  if (mode == "explicit") {
    c.mode = Mode::kExplicit;
    c.offset_s = align.number("offset_s", 0.0, -1e6, 1e6);
  } else if (mode == "trigger") {
    c.mode = Mode::kTrigger;
    if (!c.find("trigger"))
      throw Error("alignment mode 'trigger' needs channels.columns.trigger",
                  {.file = scene_file, .key = align.path_of("mode")});
    if (align.has("threshold")) c.threshold = align.number("threshold", 0.0);
    c.rising = align.choice("edge", "rising", {"rising", "falling"}) == "rising";
    if (align.has("camera_edge_s")) c.camera_edge_s = align.number("camera_edge_s", 0.0, -1e9, 1e9);
  } else {
    c.mode = Mode::kCrossCorrelation;
    if (!c.find("plate_position") && !c.find("plate_position_x"))
      throw Error("alignment mode 'cross_correlation' needs channels.columns.plate_position (or _x and _y)",
                  {.file = scene_file, .key = align.path_of("mode")});
    c.max_lag_s = align.number("max_lag_s", 0.2, 0.0, 1e3);
  }
  align.finish();
}

// channels.friction: as `tirstrain signals friction`.
void parse_friction(YamlSection& top, Config& c) {
  YamlSection friction = top.section("friction");
  c.min_normal_N = friction.number("min_normal_N", 0.05, 0.0, 1e6);
  c.events.plateau.window_s = friction.number("plateau_window_s", 0.1, 1e-6, 1e6);
  c.events.plateau.max_relative_change = friction.number("plateau_tolerance", 0.05, 1e-9, 10.0);
  c.events.plateau.min_duration_s = friction.number("plateau_min_s", 0.2, 0.0, 1e6);
  c.events.baseline_s = friction.number("baseline_s", 0.1, 1e-6, 1e6);
  c.events.plateau_fraction = friction.number("fraction", 0.9, 1e-3, 1.0);
  friction.finish();
}

// The scene's channels: section, checked strictly: every error names the scene file and the key.
Config parse_config(const Scene& scene) {
  if (scene.channels.empty())
    throw Error("the channels stage needs a 'channels:' section naming the channel file and its columns",
                {.file = scene.file, .key = "channels"});
  Config c;
  c.scene_file = scene.file;
  YamlSection top(scene.channels, scene.file, "channels");
  parse_file(top, scene.file, c);
  parse_columns(top, scene.file, c);
  check_mapping(scene.file, c);
  parse_invert(top, scene.file, c);
  parse_alignment(top, scene.file, c);
  parse_friction(top, c);
  top.finish();
  return c;
}

// One channel in SI on the channel file's samples, under the dataset name it is written with.
struct Series {
  std::string name;    // e.g. "normal_force_N"
  std::string source;  // column(s) it came from
  std::vector<double> values;
};

// Unit vector from the first sample to the sample farthest from it (the stroke direction); (1, 0) when
// nothing moves.
Vec2 excursion_direction(const std::vector<double>& x, const std::vector<double>& y) {
  double best = 0.0;
  Vec2 d{1.0, 0.0};
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double dx = x[i] - x.front(), dy = y[i] - y.front();
    const double r = std::hypot(dx, dy);
    if (r > best) {
      best = r;
      d = {dx / r, dy / r};
    }
  }
  return d;
}

// +1 or -1 so that the largest excursion from the first sample is positive.
double excursion_sign(const std::vector<double>& v) {
  double best = 0.0;
  for (double x : v)
    if (std::abs(x - v.front()) > std::abs(best)) best = x - v.front();
  return best < 0.0 ? -1.0 : 1.0;
}

// First frame whose time is at or after t; -1 when none.
std::int64_t frame_at_or_after(const std::vector<double>& frame_t_s, double t) {
  for (std::size_t k = 0; k < frame_t_s.size(); ++k)
    if (frame_t_s[k] >= t) return static_cast<std::int64_t>(k);
  return -1;
}

struct Fused {
  ts::ClockAlignment alignment;
  std::vector<double> t_s;  // channel samples on the camera clock
  std::vector<std::uint8_t> in_span;
  std::size_t frames_in_span = 0;
  std::vector<std::vector<double>> at_frames;  // per series, 0 outside the span
  std::vector<double> mu;                      // at frames, 0 where invalid
  std::vector<std::uint8_t> mu_valid;
  std::optional<ts::Plateau> mu_plateau;
  std::optional<ts::TrialEvents> events;
  std::optional<ts::FrictionTrial> trial;  // phases, tare and strokes when normal and tangential are mapped
  std::int64_t onset_frame = -1, t90_frame = -1, full_slip_frame = -1;
  std::vector<double> external_cumulative_J;  // at frames, from the onset; 0 before it and outside the span
  std::optional<double> strain_energy_at_t90_J, energy_ratio;
  std::size_t frames_with_energy = 0;
  std::vector<std::string> warnings;
};

std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// The channel file as the scene's section reads it, with every mapped column required.
ts::ChannelTable read_table(const Config& config) {
  ts::ChannelReadOptions options = config.read;
  for (const auto& m : config.mapped) options.required.push_back(m.column);
  return ts::read_channels(config.file, options);
}

class ChannelsStage final : public Stage {
 public:
  explicit ChannelsStage(Config config) : config_(std::move(config)) {}

  std::string name() const override { return "channels"; }

  // The channel file is read again by start(); what the frames brought is in the checkpoint.
  void archive(Archive& a) override {
    a(frame_t_s_, displacement_px_, energy_J_);
    if (a.reading()) fused_.reset();
  }

  void start(const TrialInfo& info) override {
    keep_history_ = info.keep_history;
    table_ = read_table(config_);
    for (const auto& name : table_.names) {
      const bool used = std::any_of(config_.mapped.begin(), config_.mapped.end(),
                                    [&](const Mapped& m) { return m.column == name; });
      if (!used) ignored_.push_back(name);
    }
    const auto si = [&](const Mapped& m) {
      std::vector<double> v = table_.column(m.column);
      const double scale = m.to_si * (m.invert ? -1.0 : 1.0);
      for (double& x : v) x *= scale;
      return v;
    };
    const auto add = [&](const std::string& name, const std::string& source, std::vector<double> v) {
      series_.push_back({name, source, std::move(v)});
      return series_.size() - 1;
    };
    std::optional<Vec2> stroke;
    if (const Mapped* m = config_.find("normal_force")) normal_ = add("normal_force_N", m->column, si(*m));
    if (const Mapped* m = config_.find("plate_position")) {
      position_ = add("plate_position_m", m->column, si(*m));
    } else if (const Mapped* mx = config_.find("plate_position_x")) {
      const Mapped* my = config_.find("plate_position_y");
      auto x = si(*mx), y = si(*my);
      const Vec2 d = excursion_direction(x, y);
      stroke = d;
      std::vector<double> along(x.size());
      for (std::size_t i = 0; i < x.size(); ++i) along[i] = d.x * x[i] + d.y * y[i];
      add("plate_position_x_m", mx->column, std::move(x));
      add("plate_position_y_m", my->column, std::move(y));
      position_ =
          add("plate_position_m", mx->column + "," + my->column + " along the stroke", std::move(along));
      stroke_direction_ = d;
    }
    if (const Mapped* m = config_.find("tangential_force")) {
      tangential_ = add("tangential_force_N", m->column, si(*m));
    } else if (const Mapped* mx = config_.find("tangential_force_x")) {
      const Mapped* my = config_.find("tangential_force_y");
      auto x = si(*mx), y = si(*my);
      const Vec2 d = stroke.value_or(excursion_direction(x, y));
      std::vector<double> along(x.size());
      for (std::size_t i = 0; i < x.size(); ++i) along[i] = d.x * x[i] + d.y * y[i];
      add("tangential_force_x_N", mx->column, std::move(x));
      add("tangential_force_y_N", my->column, std::move(y));
      tangential_ =
          add("tangential_force_N",
              mx->column + "," + my->column + (stroke ? " along the stroke" : " along its excursion"),
              std::move(along));
      force_direction_ = d;
    }
    for (const char* role : {"accelerometer", "accelerometer_nail", "accelerometer_side"})
      if (const Mapped* m = config_.find(role)) add(std::string(role) + "_m_s2", m->column, si(*m));
    if (const Mapped* m = config_.find("trigger")) trigger_ = add("trigger", m->column, si(*m));
  }

  void process(FrameContext& context) override {
    // The live view keeps no history (write() and csv_row() are not called): memory stays flat.
    remember(frame_t_s_, double{context.frame->device_time_s}, keep_history_);
    remember(displacement_px_, std::optional<Vec2>{context.plate_displacement_px}, keep_history_);
    remember(energy_J_, std::optional<double>{context.strain_energy_J}, keep_history_);
    if (config_.mode == Mode::kExplicit) early_offset_s_ = config_.offset_s;
  }

  void draw(cv::Mat& bgr, const FrameContext& context, const OverlayText& overlay) const override {
    // The offset is known while frames are drawn only when it is given explicitly.
    if (!early_offset_s_ || table_.samples() < 2) return;
    const double t = context.frame->device_time_s - *early_offset_s_;
    if (t < table_.time_s.front() || t > table_.time_s.back()) return;
    std::string text = "channels:";
    for (const std::optional<std::size_t>& index : {normal_, tangential_}) {
      if (!index) continue;
      const Series& s = series_[*index];
      const double v = ts::resample_linear(table_.time_s, s.values, {t}).front();
      text += "  " + s.name + " " + fmt(v);
    }
    overlay.status_line(bgr, 4, text, cv::Scalar(255, 255, 0));
  }

  std::vector<std::string> csv_header() const override {
    std::vector<std::string> names = {"channels_in_span"};
    for (const std::string& n : planned_names()) names.push_back(n);
    if (has_friction()) names.push_back("mu");
    return names;
  }

  void csv_row(std::size_t row, std::vector<std::string>& cells) const override {
    const Fused& f = fused();
    const bool in = f.in_span.at(row) != 0;
    cells.push_back(in ? "1" : "0");
    for (const auto& v : f.at_frames) cells.push_back(in ? format_double(v[row]) : std::string());
    if (has_friction()) cells.push_back(f.mu_valid[row] ? format_double(f.mu[row]) : std::string());
  }

  void write(H5Stream& out) const override {
    const Fused& f = fused();
    const std::size_t n = f.t_s.size(), frames = frame_t_s_.size();
    out.write("/channels/t_s", std::span<const double>(f.t_s), {n});
    out.attribute("/channels", "file", config_.file);
    out.attribute("/channels", "offset_s", f.alignment.offset_s);
    out.attribute("/channels", "alignment_method", f.alignment.method);
    out.attribute("/channels", "alignment_correlation", f.alignment.correlation);
    out.attribute("/channels", "sample_rate_Hz", table_.sample_rate_Hz);
    out.attribute("/channels", "time_axis", "camera clock: t_s = t_channel_s + offset_s, as /frames/t_s");
    for (std::size_t j = 0; j < series_.size(); ++j) {
      const std::string path = "/channels/" + series_[j].name;
      out.write(path, std::span<const double>(series_[j].values), {n});
      out.attribute(path, "source_columns", series_[j].source);
      const std::string at = "/channels/at_frames/" + series_[j].name;
      out.write(at, std::span<const double>(f.at_frames[j]), {frames});
    }
    out.write("/channels/at_frames/in_span", std::span<const std::uint8_t>(f.in_span), {frames});
    if (has_friction()) {
      out.write("/friction/mu", std::span<const double>(f.mu), {frames});
      out.write("/friction/valid", std::span<const std::uint8_t>(f.mu_valid), {frames});
      out.attribute("/friction", "min_normal_N", config_.min_normal_N);
      if (f.mu_plateau) {
        scalar(out, "/friction/mu_dynamic", f.mu_plateau->mean);
        scalar(out, "/friction/mu_dynamic_stddev", f.mu_plateau->stddev);
        scalar(out, "/friction/plateau_start_s", f.mu_plateau->start_s);
        scalar(out, "/friction/plateau_end_s", f.mu_plateau->end_s);
      }
    }
    if (f.events) {
      const ts::TrialEvents& e = *f.events;
      scalar(out, "/events/onset_s", e.onset_s);
      scalar(out, "/events/t90_s", e.fraction_s);
      scalar(out, "/events/full_slip_s", e.full_slip_s);
      for (const auto& [name, value] :
           {std::pair<const char*, std::int64_t>{"/events/onset_frame", f.onset_frame},
            {"/events/t90_frame", f.t90_frame},
            {"/events/full_slip_frame", f.full_slip_frame}}) {
        const std::int64_t v = value;
        out.write(name, std::span<const std::int64_t>(&v, 1), {1});
      }
      scalar(out, "/events/plateau_tangential_N", e.tangential_plateau.mean);
      out.attribute("/events", "fraction", config_.events.plateau_fraction);
      out.attribute("/events", "onset_source", e.onset_source);
      out.attribute("/events", "frame_rule", "first frame at or after the event; -1 when none");
      if (e.external_work_J) {
        scalar(out, "/work/external_J", *e.external_work_J);
        out.write("/work/external_cumulative_J", std::span<const double>(f.external_cumulative_J), {frames});
        if (f.strain_energy_at_t90_J) scalar(out, "/work/strain_energy_at_t90_J", *f.strain_energy_at_t90_J);
        if (f.energy_ratio) scalar(out, "/work/energy_ratio", *f.energy_ratio);
      }
    }
  }

  void summarize(nlohmann::json& summary) const override {
    const Fused& f = fused();
    nlohmann::json c;
    c["file"] = config_.file;
    nlohmann::json roles = nlohmann::json::object();
    for (const auto& m : config_.mapped)
      roles[m.role] = {{"column", m.column}, {"unit", m.unit}, {"inverted", m.invert}};
    c["columns"] = roles;
    c["ignored_columns"] = ignored_;
    if (stroke_direction_) c["stroke_direction"] = {stroke_direction_->x, stroke_direction_->y};
    if (force_direction_) c["tangential_force_direction"] = {force_direction_->x, force_direction_->y};
    c["samples"] = table_.samples();
    c["sample_rate_Hz"] = table_.sample_rate_Hz;
    c["alignment"] = {{"method", f.alignment.method},
                      {"offset_s", f.alignment.offset_s},
                      {"correlation", f.alignment.correlation}};
    if (f.alignment.method == "trigger") {
      c["alignment"]["channel_edge_s"] = f.alignment.channel_edge_s;
      c["alignment"]["camera_edge_s"] = f.alignment.camera_edge_s;
    }
    if (f.alignment.method == "cross-correlation") {
      c["alignment"]["max_lag_s"] = f.alignment.max_lag_s;
      c["alignment"]["frames_compared"] = f.alignment.samples_compared;
    }
    c["frames_in_span"] = f.frames_in_span;
    c["frames_outside_span"] = frame_t_s_.size() - f.frames_in_span;
    if (f.mu_plateau) {
      c["mu_dynamic"] = f.mu_plateau->mean;
      c["mu_dynamic_stddev"] = f.mu_plateau->stddev;
      c["mu_plateau_start_s"] = f.mu_plateau->start_s;
      c["mu_plateau_end_s"] = f.mu_plateau->end_s;
    }
    if (f.events) {
      const ts::TrialEvents& e = *f.events;
      c["events"] = {{"onset_s", e.onset_s},
                     {"onset_frame", f.onset_frame},
                     {"onset_source", e.onset_source},
                     {"baseline_end_s", e.baseline_end_s},
                     {"t90_s", e.fraction_s},
                     {"t90_frame", f.t90_frame},
                     {"fraction", config_.events.plateau_fraction},
                     {"full_slip_s", e.full_slip_s},
                     {"full_slip_frame", f.full_slip_frame},
                     {"plateau_tangential_N", e.tangential_plateau.mean}};
      if (e.external_work_J) c["external_work_J"] = *e.external_work_J;
    }
    if (f.trial) {
      c["phases"] = ts::phases_json(f.trial->phases);
      c["mu_over"] = "the whole first slide (phases.strokes[0]), on the tared channels";
    }
    c["frames_with_strain_energy"] = f.frames_with_energy;
    if (f.strain_energy_at_t90_J) c["strain_energy_at_t90_J"] = *f.strain_energy_at_t90_J;
    if (f.energy_ratio) c["energy_ratio"] = *f.energy_ratio;
    c["warnings"] = f.warnings;
    summary["channels"] = c;
  }

 private:
  static void scalar(H5Stream& out, const std::string& name, double value) {
    out.write(name, std::span<const double>(&value, 1), {1});
  }

  bool has_friction() const { return config_.find("normal_force") && has_tangential(); }
  bool has_tangential() const {
    return config_.find("tangential_force") || config_.find("tangential_force_x");
  }

  // Dataset names in the order start() creates them (known before the file is read).
  std::vector<std::string> planned_names() const {
    std::vector<std::string> names;
    if (config_.find("normal_force")) names.push_back("normal_force_N");
    if (config_.find("plate_position")) names.push_back("plate_position_m");
    if (config_.find("plate_position_x"))
      names.insert(names.end(), {"plate_position_x_m", "plate_position_y_m", "plate_position_m"});
    if (config_.find("tangential_force")) names.push_back("tangential_force_N");
    if (config_.find("tangential_force_x"))
      names.insert(names.end(), {"tangential_force_x_N", "tangential_force_y_N", "tangential_force_N"});
    for (const char* role : {"accelerometer", "accelerometer_nail", "accelerometer_side"})
      if (config_.find(role)) names.push_back(std::string(role) + "_m_s2");
    if (config_.find("trigger")) names.push_back("trigger");
    return names;
  }

  // Errors from the library carry no file; name the channel file (or the scene for alignment settings).
  template <typename Fn>
  auto located(const std::string& file, const std::string& column, const std::string& key, Fn fn) const
      -> decltype(fn()) {
    return with_error_context(fn, [&](ErrorContext& ctx) {
      ctx.file = file;
      if (ctx.column.empty()) ctx.column = column;
      ctx.key = key;
    });
  }

  ts::ClockAlignment align() const {
    const std::string scene_file = config_.scene_file;
    switch (config_.mode) {
      case Mode::kExplicit:
        return ts::align_explicit(config_.offset_s);
      case Mode::kTrigger: {
        const double camera_edge = config_.camera_edge_s.value_or(frame_t_s_.front());
        return located(config_.file, config_.find("trigger")->column, "channels.alignment", [&] {
          return ts::align_by_trigger_channel(table_.time_s, series_[*trigger_].values, camera_edge,
                                              config_.threshold, config_.rising);
        });
      }
      case Mode::kCrossCorrelation: {
        std::vector<double> t_cam, x, y;
        for (std::size_t k = 0; k < frame_t_s_.size(); ++k)
          if (displacement_px_[k]) {
            t_cam.push_back(frame_t_s_[k]);
            x.push_back(displacement_px_[k]->x);
            y.push_back(displacement_px_[k]->y);
          }
        if (t_cam.size() < 4)
          throw Error(
              "cross-correlation alignment needs the image-measured plate displacement (the tracking "
              "stage with a reference pattern on the glass) in at least 4 frames; it is available in " +
                  std::to_string(t_cam.size()),
              {.file = scene_file, .key = "channels.alignment.mode"});
        // Both series oriented so their largest excursion is positive: image axes and rig axes may differ.
        const Vec2 d = excursion_direction(x, y);
        std::vector<double> along(x.size());
        for (std::size_t i = 0; i < x.size(); ++i) along[i] = d.x * x[i] + d.y * y[i];
        std::vector<double> plate = series_[*position_].values;
        const double sign = excursion_sign(plate);
        for (double& p : plate) p *= sign;
        return located(scene_file, "", "channels.alignment.max_lag_s", [&] {
          return ts::align_by_cross_correlation(table_.time_s, plate, t_cam, along, config_.max_lag_s);
        });
      }
    }
    return {};
  }

  // μ per slide and the events inside the phases of the tared channels (signals/friction_trial.hpp); the
  // phases' and the consistency checks' warnings go into summary.json with their codes.
  void measure_friction(Fused& f) const {
    ts::FrictionTrialOptions options;
    options.phases.min_normal_N = config_.min_normal_N;
    options.events = config_.events;
    const std::vector<double>* position = position_ ? &series_[*position_].values : nullptr;
    try {
      f.trial = ts::analyse_friction_trial(f.t_s, series_[*normal_].values, series_[*tangential_].values,
                                           position, options);
    } catch (const Error& e) {
      f.warnings.push_back("friction not measured: " + e.message());
    }
    if (f.trial) {
      for (const auto& w : f.trial->warnings) f.warnings.push_back(w.code + ": " + w.message);
      const ts::Stroke& s = f.trial->phases.strokes.front();
      f.mu_plateau = ts::Plateau{0, 0, s.slide_start_s, s.slide_end_s, s.mu_mean, s.mu_sd};
      f.events = f.trial->events;
    }
    mu_at_frames(f);
  }

  // F_t/W at the frames in the channel record: on the tared channels when the phases were found, as
  // recorded otherwise; valid where W ≥ min_normal_N.
  void mu_at_frames(Fused& f) const {
    const std::size_t frames = frame_t_s_.size();
    std::vector<double> w = f.at_frames[*normal_], ft = f.at_frames[*tangential_];
    if (f.trial) {
      std::vector<double> query;
      for (std::size_t k = 0; k < frames; ++k)
        if (f.in_span[k]) query.push_back(frame_t_s_[k]);
      const auto wq = ts::resample_linear(f.t_s, f.trial->phases.normal_N, query);
      const auto fq = ts::resample_linear(f.t_s, f.trial->phases.tangential_N, query);
      for (std::size_t k = 0, q = 0; k < frames; ++k)
        if (f.in_span[k]) {
          w[k] = wq[q];
          ft[k] = fq[q++];
        }
    }
    f.mu.assign(frames, 0.0);
    f.mu_valid.assign(frames, 0);
    for (std::size_t k = 0; k < frames; ++k)
      if (f.in_span[k] && w[k] >= config_.min_normal_N && w[k] > 0.0) {
        f.mu[k] = ft[k] / w[k];
        f.mu_valid[k] = 1;
      }
  }

  std::vector<std::string> warnings() const override { return fused().warnings; }

  const Fused& fused() const {
    if (fused_) return *fused_;
    if (frame_t_s_.empty() || series_.empty())
      throw Error("internal: the channels stage was not started or saw no frame", {.file = config_.file});
    Fused f;
    const std::size_t frames = frame_t_s_.size();
    f.alignment = align();
    f.t_s = table_.time_s;
    for (double& t : f.t_s) t += f.alignment.offset_s;

    // Frames inside the channel record get interpolated values; the rest 0 and in_span = 0.
    f.in_span.assign(frames, 0);
    std::vector<double> query;
    std::vector<std::size_t> query_frame;
    for (std::size_t k = 0; k < frames; ++k)
      if (frame_t_s_[k] >= f.t_s.front() && frame_t_s_[k] <= f.t_s.back()) {
        f.in_span[k] = 1;
        query.push_back(frame_t_s_[k]);
        query_frame.push_back(k);
      }
    f.frames_in_span = query.size();
    if (f.frames_in_span < frames)
      f.warnings.push_back(std::to_string(frames - f.frames_in_span) +
                           " frame(s) lie outside the channel record on the camera clock (" +
                           fmt(f.t_s.front()) + " to " + fmt(f.t_s.back()) +
                           " s); their channel values are absent (in_span = 0)");
    for (const Series& s : series_) {
      std::vector<double> at(frames, 0.0);
      if (!query.empty()) {
        const auto v = ts::resample_linear(f.t_s, s.values, query);
        for (std::size_t q = 0; q < query.size(); ++q) at[query_frame[q]] = v[q];
      }
      f.at_frames.push_back(std::move(at));
    }

    if (normal_ && tangential_) {
      measure_friction(f);
    } else if (tangential_) {
      try {
        const std::vector<double>* position = position_ ? &series_[*position_].values : nullptr;
        f.events = ts::detect_events(f.t_s, series_[*tangential_].values, position, config_.events);
      } catch (const Error& e) {
        f.warnings.push_back("events not detected: " + e.message());
      }
    }
    if (f.events) {
      const ts::TrialEvents& e = *f.events;
      if (e.baseline_shortened)
        f.warnings.push_back("the movement starts inside the " + fmt(config_.events.baseline_s) +
                             " s baseline window (friction.baseline_s): the baseline ends at " +
                             fmt(e.baseline_end_s) + " s, before it");
      f.onset_frame = frame_at_or_after(frame_t_s_, e.onset_s);
      f.t90_frame = frame_at_or_after(frame_t_s_, e.fraction_s);
      f.full_slip_frame = frame_at_or_after(frame_t_s_, e.full_slip_s);
      if (e.external_work_J) {
        const auto& ft = series_[*tangential_].values;
        const auto& x = series_[*position_].values;
        f.external_cumulative_J.assign(frames, 0.0);
        for (std::size_t k = 0; k < frames; ++k)
          if (f.in_span[k] && frame_t_s_[k] > e.onset_s)
            f.external_cumulative_J[k] = ts::external_work_J(f.t_s, ft, x, e.onset_s, frame_t_s_[k]);
        // U at the 90 % point: linear between the frames with strain energy that bracket it.
        std::vector<double> tu, u;
        for (std::size_t k = 0; k < frames; ++k)
          if (energy_J_[k]) {
            tu.push_back(frame_t_s_[k]);
            u.push_back(*energy_J_[k]);
          }
        f.frames_with_energy = tu.size();
        if (tu.size() >= 2 && e.fraction_s >= tu.front() && e.fraction_s <= tu.back()) {
          f.strain_energy_at_t90_J = ts::resample_linear(tu, u, {e.fraction_s}).front();
          if (*e.external_work_J != 0.0) f.energy_ratio = *f.strain_energy_at_t90_J / *e.external_work_J;
          // Elastic energy stored cannot exceed the work done on the skin.
          if (f.energy_ratio && std::abs(*f.energy_ratio) > 1.0)
            f.warnings.push_back("U/U_ext = " + fmt(*f.energy_ratio) +
                                 ": the strain energy exceeds the work of the tangential force, which cannot "
                                 "be; check the tissue's E and depth, the force and position units, and the "
                                 "events (onset, t90)");
        } else if (!tu.empty()) {
          f.warnings.push_back("the 90 % point (" + fmt(e.fraction_s) +
                               " s) is not bracketed by frames with strain energy; U/U_ext not reported");
        }
      }
    }
    fused_ = std::move(f);
    return *fused_;
  }

  Config config_;
  ts::ChannelTable table_;
  std::vector<Series> series_;
  std::vector<std::string> ignored_;
  std::optional<std::size_t> normal_, tangential_, position_, trigger_;
  std::optional<Vec2> stroke_direction_, force_direction_;
  std::optional<double> early_offset_s_;
  bool keep_history_ = true;
  std::vector<double> frame_t_s_;
  std::vector<std::optional<Vec2>> displacement_px_;
  std::vector<std::optional<double>> energy_J_;
  mutable std::optional<Fused> fused_;
};

}  // namespace

std::unique_ptr<Stage> make_channels_stage(const Scene& scene) {
  return std::make_unique<ChannelsStage>(parse_config(scene));
}

void check_channel_file(const Scene& scene) {
  (void)read_table(parse_config(scene));
}

}  // namespace tirstrain::pipeline
