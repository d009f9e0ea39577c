// `tirstrain signals phases` and `tirstrain signals friction` end to end on a synthetic recording written
// as CSV: the JSON against the recording's truth, the PNG's shading where the phases are, the named
// warning and the error a negative-going normal force gives.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "tests/signals/cli_run.hpp"

#include "core/csv.hpp"
#include "signals/phases_plot.hpp"
#include "tests/signals/synthetic_recording.hpp"

namespace ts = tirstrain::signals;

namespace {

std::string dir() {
  return tirstrain::testing::test_dir("signals_phases_cli");
}

using Run = tirstrain::testing::CliRun;

Run run(const std::string& args) {
  return tirstrain::testing::run_cli(args);
}

std::string write_recording(const ts::testing::SynthOutput& rec) {
  const std::string path = dir() + "/recording.csv";
  tirstrain::CsvWriter out(path, {"t_s", "normal_N", "lateral_N", "x_m"});
  for (std::size_t i = 0; i < rec.t_s.size(); ++i)
    out.row({rec.t_s[i], rec.normal_N[i], rec.tangential_N[i], rec.position_m[i]});
  out.commit();
  return path;
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

}  // namespace

TEST(SignalsPhasesCli, PhasesJsonAndPlot) {
  ts::testing::SynthRecording c;
  c.strokes = 3;
  const auto rec = ts::testing::synthesise(c);
  const std::string in = write_recording(rec), out = dir() + "/phases.json";
  const auto r =
      run("signals phases " + in + " --normal normal_N --tangential lateral_N --position x_m --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto j = read_json(out);
  EXPECT_NEAR(j.at("contact_start_s").get<double>(), c.contact_s, 0.02);
  EXPECT_NEAR(j.at("loaded_s").get<double>(), c.loaded_s, 0.02);
  EXPECT_NEAR(j.at("release_s").get<double>(), c.release_s, 0.02);
  ASSERT_EQ(j.at("strokes").size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    const auto& s = j.at("strokes")[k];
    EXPECT_NEAR(s.at("slide_start_s").get<double>(), rec.strokes[k].slide_start_s, 0.02);
    EXPECT_NEAR(s.at("slide_end_s").get<double>(), rec.strokes[k].slide_end_s, 0.02);
    EXPECT_NEAR(s.at("mu_mean").get<double>() / rec.strokes[k].mu_mean, 1.0, 0.02);
    EXPECT_EQ(s.at("direction").get<int>(), rec.strokes[k].direction);
    EXPECT_EQ(s.at("direction_source"), "position");
  }
  EXPECT_EQ(j.at("tare").at("model"), "linear");
  EXPECT_NEAR(j.at("tare").at("tangential").at("drift_N_per_s").get<double>(), c.drift_tangential_N_s, 5e-4);
  EXPECT_TRUE(j.at("warnings").empty());
  // Phases in order: approach, press, then loading/slide per stroke, ..., release, after_contact.
  const auto& phases = j.at("phases");
  EXPECT_EQ(phases.front().at("name"), "approach");
  EXPECT_EQ(phases[1].at("name"), "press");
  EXPECT_EQ(phases.back().at("name"), "after_contact");

  // The plot: the middle of each slide is shaded as a slide, the middle of the approach as no contact.
  const std::string png = dir() + "/phases.png";
  ASSERT_EQ(j.at("plot"), png);
  const cv::Mat img = cv::imread(png);
  ASSERT_FALSE(img.empty());
  ts::PhasesPlotLayout layout;
  ts::Phases p;
  p.normal_N.assign(rec.t_s.size(), 0.0);
  p.tangential_N = p.normal_N;
  const cv::Mat reference = ts::render_phases_plot(rec.t_s, p, {}, &layout);
  ASSERT_EQ(img.size(), reference.size());
  const auto x_of = [&](double t) {
    return layout.left +
           static_cast<int>(std::lround((t - rec.t_s.front()) / (rec.t_s.back() - rec.t_s.front()) *
                                        (layout.right - layout.left)));
  };
  const int y = layout.panel_bottom[0] - 3;  // below the trace's zero line, above the frame
  const auto colour_at = [&](double t) {
    const cv::Vec3b v = img.at<cv::Vec3b>(y, x_of(t));
    return cv::Scalar(v[0], v[1], v[2]);
  };
  for (const auto& s : rec.strokes)
    EXPECT_EQ(colour_at(0.5 * (s.slide_start_s + s.slide_end_s)), ts::phase_colour("slide"));
  EXPECT_EQ(colour_at(1.0), ts::phase_colour("approach"));
  EXPECT_EQ(colour_at(0.5 * (c.contact_s + c.loaded_s)), ts::phase_colour("press"));
}

TEST(SignalsPhasesCli, FrictionInsideThePhasesAndTheNormalForceSign) {
  ts::testing::SynthRecording c;
  c.first_stroke_s = 4.44;
  c.slide_into_release = true;
  c.normal_sign = -1;
  const auto rec = ts::testing::synthesise(c);
  const std::string in = write_recording(rec), mu = dir() + "/mu.csv", summary = dir() + "/friction.json";
  const std::string common = "signals friction " + in + " --normal normal_N --tangential lateral_N --out " +
                             mu + " --summary " + summary;
  // As recorded: the normal force goes negative on contact, so there is no μ: an error that says why.
  auto r = run(common);
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("normal_force_negative"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("no slide"), std::string::npos) << r.output;
  // With the sign set: μ over the whole slide, events inside the phases.
  r = run(common + " --invert-normal");
  ASSERT_EQ(r.code, 0) << r.output;
  const auto j = read_json(summary);
  const auto& truth = rec.strokes[0];
  EXPECT_NEAR(j.at("mu_dynamic").get<double>() / truth.mu_mean, 1.0, 0.02);
  EXPECT_NEAR(j.at("mu_plateau_start_s").get<double>(), truth.slide_start_s, 0.02);
  EXPECT_NEAR(j.at("mu_plateau_end_s").get<double>(), truth.slide_end_s, 0.02);
  EXPECT_GE(j.at("onset_s").get<double>(), j.at("phases").at("loaded_s").get<double>());
  EXPECT_LE(j.at("full_slip_s").get<double>(), j.at("mu_plateau_end_s").get<double>());
  EXPECT_EQ(j.at("signs").at("normal_inverted"), true);
  EXPECT_TRUE(j.at("warnings").empty()) << j.at("warnings").dump();
  EXPECT_EQ(j.at("strokes").size(), 1u);
}

TEST(SignalsPhasesCli, HelpDescribesTheVerbWithAnExample) {
  const auto r = run("signals phases --help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.output.find("approach"), std::string::npos);
  EXPECT_NE(r.output.find("Example:"), std::string::npos);
  EXPECT_NE(r.output.find("--tare-s"), std::string::npos);
  const auto list = run("signals --help");
  EXPECT_NE(list.output.find("phases"), std::string::npos);
}
