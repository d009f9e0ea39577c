#pragma once
// Channel files (force, accelerometer, position, trigger ...) read, validated and put on one time axis.
//
// Formats:
//   - CSV with a header row of names, units in the name ("tangential_N"); the time column (default "t_s").
//   - HDF5 with one 1-D numeric dataset per channel inside a group (default "/"). MATLAB writes arrays
//     transposed (column-major), so an N×1 column vector arrives as a 1×N dataset; any dataset whose shape
//     has one non-singleton dimension is taken as a vector. Character arrays (MATLAB_class "char", stored
//     as uint16), cells, structs and non-numeric types are rejected by name.
//   - MATLAB .mat of every version (v4, v5, v7 compressed, v7.3) through libmatio (read_channels_mat);
//     a v7.3 file matio cannot open is read by the HDF5 reader above. A channel is a variable `NAME`, a
//     matrix column `NAME[:,k]` or row `NAME[k,:]` (1-based, as in MATLAB), a struct field `a.b.c` (with
//     or without a column), or a column of a matrix named in `mat_column_names`.
// Without a time column, `rate_Hz` gives the sample times (i / rate_Hz); without either, it is an error.
// `calibration` then maps raw values (DAQ volts) to physical units per channel: gain * raw + offset.
//
// Validation (every failure is a tirstrain::Error naming file, row (CSV line, header = row 1) or sample
// index (HDF5), and column): missing requested columns, columns not in an `expected` list when one is
// given, NaN/Inf/empty cells, channels of different lengths, duplicate or decreasing timestamps, and a
// sample interval that deviates from the median interval by more than `rate_tolerance` (relative).
// Nothing is interpolated or repaired.
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace tirstrain::signals {

// Seconds per unit of a time column or variable named with a unit suffix (`t_ms`: 1e-3, `_us`, `_ns`,
// `_min`) or a bracketed unit (`t [ms]`, `time (us)`); 1 for `_s` and for a name with no time unit, which
// is read as seconds. Readers convert the time
// axis with it, so `ChannelTable::time_s` is always in seconds.
double time_column_seconds_per_unit(const std::string& name);
// The name a time column takes once its values are in seconds: the unit suffix becomes `_s` (`t_ms` ->
// `t_s`); a name without a time unit is kept. Outputs write their time axis under it.
std::string seconds_column_name(const std::string& name);

// Physical quantities whose unit a channel's column name carries as a suffix ("plate_x_mm").
enum class Quantity { kForce, kPosition, kAcceleration };

struct ColumnUnit {
  const char* name;  // as in the suffix: "mm"
  double to_si;      // SI units per unit: 1e-3 for mm
};

// The units a column of `quantity` may be named with; the first is the SI unit.
std::vector<ColumnUnit> column_units(Quantity quantity);
// The units of `quantity` as a list for messages: "m, mm, um".
std::string column_unit_list(Quantity quantity);
// The unit `column` ends with, "_" and a name of column_units (the longest that matches, so "_mm" is not
// read as "_m"), or in brackets as spreadsheets write it ("Fz [mN]", "x (mm)", "a [m/s^2]", "[µm]");
// nullopt when the name carries none of them.
std::optional<ColumnUnit> unit_of_column_name(const std::string& column, Quantity quantity);
// Whether `column` ends with a unit in brackets ("Fz [kN]"), known or not.
bool names_a_bracketed_unit(const std::string& column);

struct ChannelTable {
  std::string path;
  std::string time_column = "t_s";
  std::vector<double> time_s;
  std::vector<std::string> names;            // channel names (time column excluded), in file order
  std::vector<std::vector<double>> columns;  // columns[j][i]
  double sample_rate_Hz = 0.0;               // 1 / median interval
  std::string time_source;                   // the time column's name, or how times were made from a rate
  // Maps a sample index to the row number a user sees in the file (CSV line), or -1 for HDF5.
  long first_data_row = 2;

  std::size_t samples() const { return time_s.size(); }
  bool has(const std::string& name) const;
  // Throws Error naming the file and the missing column, listing the ones present.
  const std::vector<double>& column(const std::string& name) const;
};

// raw -> physical: value = gain * raw + offset (e.g. a force sensor's N/V and its zero in N).
struct ChannelCalibration {
  double gain = 1.0;    // physical units per raw unit (N/V, m/s² per V, ...)
  double offset = 0.0;  // physical units added after the gain
};

struct ChannelReadOptions {
  std::string time_column = "t_s";
  std::vector<std::string> required;  // must be present
  std::vector<std::string> expected;  // when non-empty, any other column is an "unknown column" error
  double rate_tolerance = 0.01;       // max |dt_i − median dt| / median dt
  std::string hdf5_group = "/";
  // Sample rate of a file holding no time column, Hz: sample i is at i / rate_Hz s. Unset: the time
  // column is required. Given for a file that has a time column, it is an error (two clocks).
  std::optional<double> rate_Hz;
  // .mat: the column names of matrix variables, in column order ("dataQ" -> {"lateral_N", "normal_N"});
  // each named column becomes a channel. The key may be a struct path ("rec.data").
  std::map<std::string, std::vector<std::string>> mat_column_names;
  // Per channel name: raw -> physical units, applied after reading (channels not named stay raw).
  std::map<std::string, ChannelCalibration> calibration;
  // HDF5 files (and MATLAB v7.3, read through HDF5) are read once in a child process first, so that a file
  // on which the library crashes is refused with an error rather than ending this process
  // (signals/isolated_read.hpp). Off only where the crash itself is wanted (the fuzz targets).
  bool read_in_child_first = true;
};

// Dispatches on the extension: .mat as MATLAB; .h5, .hdf5 as HDF5; anything else as CSV.
ChannelTable read_channels(const std::string& path, const ChannelReadOptions& options = {});
ChannelTable read_channels_mat(const std::string& path, const ChannelReadOptions& options = {});
ChannelTable read_channels_csv(const std::string& path, const ChannelReadOptions& options = {});
ChannelTable read_channels_hdf5(const std::string& path, const ChannelReadOptions& options = {});

// Checks the time axis as described above and returns the sample rate (1 / median interval).
// `where` names the source for messages; `first_row` is the user-visible row of sample 0 (or -1 for
// sample indices).
double validate_time_axis(const std::vector<double>& time_s, double rate_tolerance, const std::string& where,
                          const std::string& column, long first_row);

// Sample times 0, 1/rate_Hz, 2/rate_Hz, ... of `count` samples (rate_Hz checked positive and finite; `where`
// names the file for the message).
std::vector<double> times_from_rate(std::size_t count, double rate_Hz, const std::string& where);

// gain * raw + offset on the channels named in `calibration`; a calibration naming no channel of the table
// is an error (a typo would leave volts labelled as newtons).
void apply_calibration(ChannelTable& table, const std::map<std::string, ChannelCalibration>& calibration);

// Linear interpolation of a channel at query times (e.g. frame timestamps). A query outside
// [time_s.front(), time_s.back()] is an error naming the query index as a frame: nothing is extrapolated.
std::vector<double> resample_linear(const std::vector<double>& time_s, const std::vector<double>& values,
                                    const std::vector<double>& query_s);

// Time of the first crossing of `threshold` (rising: from below to at-or-above; falling: the reverse),
// linearly interpolated between samples; nullopt when the signal never crosses.
std::optional<double> first_crossing_s(const std::vector<double>& time_s, const std::vector<double>& values,
                                       double threshold, bool rising = true, std::size_t start_index = 0);

// Clock offset between a channel clock and the camera clock: t_camera = t_channel + offset_s.
// Three ways to get it (the pipeline's `channels.alignment.mode`, `tirstrain signals align`):
//   explicit           a known offset (default 0: both clocks are the same);
//   trigger            an edge seen on a trigger channel and its time on the camera clock;
//   cross-correlation  the plate position channel against the image-measured plate displacement.
struct ClockAlignment {
  double offset_s = 0.0;
  double correlation = 0.0;  // normalised cross-correlation at the optimum (1 = identical shapes)
  std::string method;        // "explicit", "trigger", "cross-correlation"
  // trigger: the edge on each clock; cross-correlation: the lag range searched and the samples compared.
  double channel_edge_s = 0.0;
  double camera_edge_s = 0.0;
  double max_lag_s = 0.0;
  std::size_t samples_compared = 0;
};

ClockAlignment align_explicit(double offset_s);

// From a shared trigger: the same edge seen at trigger_channel_s on the channel clock and at
// trigger_camera_s on the camera clock.
ClockAlignment align_by_trigger(double trigger_channel_s, double trigger_camera_s);

// The same with the channel-side edge found on a trigger channel: the first crossing of `threshold`
// (rising or falling, linearly interpolated between samples). Without a threshold, the midpoint between
// the channel's minimum and maximum (the 50 % level of a logic pulse). Throws Error when the channel is
// constant or never crosses.
ClockAlignment align_by_trigger_channel(const std::vector<double>& time_s, const std::vector<double>& trigger,
                                        double trigger_camera_s, std::optional<double> threshold = {},
                                        bool rising = true);

// Cross-correlates the channel's plate position p(t_channel) with the image-measured plate displacement
// c(t_camera). For a trial offset τ the channel is linearly interpolated at every camera time minus τ (the
// dense series is evaluated at the sparse times, so the coarse camera series is never interpolated) and the
// Pearson correlation of the pairs is taken; τ runs over [-max_lag_s, max_lag_s] in steps of the channel's
// sample interval, the best step is refined by a parabola through its neighbours and then by a
// golden-section search of the continuous correlation within ±1 step (sub-sample resolution). Both series
// are mean-removed over the compared pairs and their units need not match; a sign flip between them is not
// undone (orient both along the motion first). Throws Error when fewer than 4 camera samples overlap the
// channel at every lag or a series is constant.
// The series turned so that its largest excursion from its first sample is positive: a plate position and
// an image-measured displacement of the same motion may have opposite signs, which the correlation does not
// undo.
std::vector<double> oriented_along_motion(std::vector<double> series);

ClockAlignment align_by_cross_correlation(const std::vector<double>& channel_time_s,
                                          const std::vector<double>& channel_position,
                                          const std::vector<double>& camera_time_s,
                                          const std::vector<double>& camera_displacement, double max_lag_s);

}  // namespace tirstrain::signals
