// `tirstrain signals <verb>` end to end: the real binary on files written here; outputs checked against
// the library's numbers and the documented CSV/JSON contract; bad input gives exit 1 and a located message.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include <nlohmann/json.hpp>

#include "tests/signals/cli_run.hpp"

#include "core/csv.hpp"
#include "signals/channels.hpp"
#include "signals/filter.hpp"

namespace ts = tirstrain::signals;

namespace {

std::string dir() {
  return tirstrain::testing::test_dir("signals_cli");
}

using Run = tirstrain::testing::CliRun;

Run run(const std::string& args) {
  return tirstrain::testing::run_cli(args);
}

// 4 s at 1 kHz: force = 10 Hz + 200 Hz sines, accel = force through a 3-tap FIR.
std::string write_trial() {
  const std::string path = dir() + "/trial.csv";
  std::ofstream out(path);
  out << "t_s,force_N,accel_m_s2\n";
  double f1 = 0.0, f2 = 0.0;
  for (int i = 0; i < 4000; ++i) {
    const double t = i / 1000.0;
    const double f = std::sin(2 * std::numbers::pi * 10 * t) +
                     0.5 * std::sin(2 * std::numbers::pi * 200 * t) +
                     0.2 * std::sin(2 * std::numbers::pi * 77.7 * t * t);
    out << tirstrain::format_double(t) << ',' << tirstrain::format_double(f) << ','
        << tirstrain::format_double(0.5 * f + 0.3 * f1 - 0.2 * f2) << '\n';
    f2 = f1;
    f1 = f;
  }
  return path;
}

// The friction tests' slide, sample i of 2001 at 1 kHz: W = 2 N; the plate still until 0.5 s, then at
// 10 mm/s; F_t follows the Cattaneo–Mindlin curve 1.6 (1 − (1 − u)^1.5) N to μW = 1.6 N over 2 mm.
struct SlideSample {
  double t_s, slide_m, tangential_N;
};
SlideSample slide_at(int i) {
  const double t = i / 1000.0, d = std::max(0.0, 0.01 * (t - 0.5)), u = std::min(1.0, d / 0.002);
  return {t, d, 1.6 * (1 - std::pow(1 - u, 1.5))};
}

// U_ext = ∫F dx from onset to t90 of that slide in closed form: 3.2 mJ · (u90 + ((1 − u90)^2.5 − 1) / 2.5).
double slide_external_work_J() {
  const double u90 = 1 - std::pow(0.1, 2.0 / 3.0);
  return 3.2e-3 * (u90 + (std::pow(1 - u90, 2.5) - 1) / 2.5);
}

}  // namespace

TEST(SignalsCli, FilterWritesZeroPhaseOutputMatchingTheLibrary) {
  const std::string in = write_trial(), out = dir() + "/filtered.csv";
  const auto r = run("signals filter " + in + " --column force_N --order 4 --lowpass-Hz 80 --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto table = tirstrain::read_numeric_csv(out);
  ASSERT_EQ(table.names, (std::vector<std::string>{"t_s", "force_N_filtered"}));
  const auto input = tirstrain::read_numeric_csv(in);
  // The sample rate is 1/median interval of t_s, as the CLI derives it.
  const double fs = ts::read_channels(in).sample_rate_Hz;
  const auto expected =
      ts::butterworth_filtfilt(input.column("force_N"), {ts::FilterType::lowpass, 4, 80.0, 0.0, fs});
  for (std::size_t i = 0; i < expected.size(); ++i) ASSERT_DOUBLE_EQ(table.columns[1][i], expected[i]);
  EXPECT_FALSE(std::filesystem::exists(out + ".partial"));
}

// A time column in ms is read in ms and written in s, under a name that says so: filter, resample (its
// --times in ms too) and friction's mu all give t_s, and the filtered series's spectrum peaks at its tone.
TEST(SignalsCli, ATimeColumnInMillisecondsIsWrittenInSecondsAsTS) {
  const std::string in = dir() + "/ms.csv", times = dir() + "/times_ms.csv";
  {
    std::ofstream out(in);
    out << "t_ms,normal_N,tangential_N\n";
    for (int i = 0; i < 2000; ++i)
      out << i << ',' << tirstrain::format_double(1.0 + std::sin(2 * std::numbers::pi * 20 * i / 1000.0))
          << ",0.5\n";
    std::ofstream(times) << "when_ms\n100\n250.5\n";
  }
  const std::string filtered = dir() + "/ms_filtered.csv";
  ASSERT_EQ(
      run("signals filter " + in + " --time-column t_ms --column normal_N --lowpass-Hz 80 --out " + filtered)
          .code,
      0);
  const auto f = tirstrain::read_numeric_csv(filtered);
  ASSERT_EQ(f.names[0], "t_s");
  EXPECT_DOUBLE_EQ(f.columns[0][1000], 1.0);
  const std::string peaks = dir() + "/ms_peaks.csv";
  ASSERT_EQ(run("signals psd " + filtered + " --column normal_N_filtered --segment 500 --peaks-out " + peaks +
                " --out " + dir() + "/ms_psd.csv")
                .code,
            0);
  const auto p = tirstrain::read_numeric_csv(peaks);
  const auto& psd = p.column("psd");
  ASSERT_FALSE(psd.empty());
  const auto top = static_cast<std::size_t>(std::max_element(psd.begin(), psd.end()) - psd.begin());
  EXPECT_NEAR(p.column("freq_Hz")[top], 20.0, 2.0);
  const std::string resampled = dir() + "/ms_resampled.csv";
  const auto r = run("signals resample " + in + " --time-column t_ms --times " + times +
                     " --times-column when_ms --out " + resampled);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto s = tirstrain::read_numeric_csv(resampled);
  ASSERT_EQ(s.names[0], "t_s");
  EXPECT_DOUBLE_EQ(s.columns[0][1], 0.2505);
  EXPECT_NEAR(s.column("normal_N")[1], 1.0 + std::sin(2 * std::numbers::pi * 20 * 0.2505), 0.02);
}

TEST(SignalsCli, PsdAndTfFollowTheContract) {
  const std::string in = write_trial(), psd = dir() + "/psd.csv", tf = dir() + "/tf.csv";
  auto r = run("signals psd " + in + " --column force_N --segment 500 --out " + psd);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto p = tirstrain::read_numeric_csv(psd);
  ASSERT_EQ(p.names, (std::vector<std::string>{"freq_Hz", "psd"}));
  ASSERT_EQ(p.rows(), 251u);
  // 10 Hz on bin 5 (2 Hz bins), amplitude 1: density A²·N/(3·fs) = 500/3000.
  EXPECT_NEAR(p.columns[1][5], 500.0 / 3000.0, 1e-3);
  r = run("signals tf " + in + " --input force_N --output accel_m_s2 --segment 500 --out " + tf);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto t = tirstrain::read_numeric_csv(tf);
  ASSERT_EQ(t.names, (std::vector<std::string>{"freq_Hz", "gain", "phase_rad", "coherence"}));
  // At 10 Hz the FIR gain is |0.5 + 0.3 e^{-jω} − 0.2 e^{-2jω}|.
  const double w = 2 * std::numbers::pi * 10.0 / 1000.0;
  const double gain =
      std::abs(std::complex<double>(0.5) + 0.3 * std::polar(1.0, -w) - 0.2 * std::polar(1.0, -2 * w));
  EXPECT_NEAR(t.columns[1][5], gain, 0.01 * gain);
  EXPECT_GT(t.columns[3][5], 0.99);
}

TEST(SignalsCli, RqaJsonHasTheFourMeasures) {
  const std::string in = write_trial(), out = dir() + "/rqa.json";
  const auto r =
      run("signals rqa " + in + " --column force_N --dim 3 --delay 5 --recurrence-rate 0.05 --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream f(out);
  const auto j = nlohmann::json::parse(f);
  for (const char* key : {"recurrence_rate", "determinism", "mean_diagonal_length", "laminarity"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_NEAR(j["recurrence_rate"].get<double>(), 0.05, 0.001);
  const auto bad = run("signals rqa " + in + " --column force_N --dim 3 --delay 5 --out " + out);
  EXPECT_EQ(bad.code, 2);  // the command line is wrong
  EXPECT_NE(bad.output.find("--recurrence-rate"), std::string::npos);
  const auto help = run("signals rqa --help");
  EXPECT_NE(help.output.find("line of identity is excluded"), std::string::npos);
  EXPECT_NE(help.output.find("Euclidean"), std::string::npos);
}

TEST(SignalsCli, RecurrenceInTheSpatialDomainAcrossAnEnsembleAndAsAPicture) {
  // Two profiles sampled every 0.01 mm: a 0.5 mm sine with a little noise, lengths also reported in mm.
  std::vector<std::string> files;
  for (int trial = 0; trial < 2; ++trial) {
    files.push_back(dir() + "/profile" + std::to_string(trial) + ".csv");
    std::ofstream out(files.back());
    out << "x_mm,height_um\n";
    for (int i = 0; i < 500; ++i)
      out << tirstrain::format_double(i * 0.01) << ','
          << tirstrain::format_double(std::sin(2 * std::numbers::pi * i * 0.01 / 0.5 + trial) +
                                      0.02 * std::sin(i * 1.7))
          << '\n';
  }
  const std::string both = files[0] + " " + files[1], common = " --column height_um --dim 2 --delay 12 ";
  const std::string json_out = dir() + "/rqa_spatial.json";
  const auto r = run("signals rqa " + both + common + "--time-column x_mm --spatial --ensemble sum " +
                     "--recurrence-rate 0.05 --out " + json_out);
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream f(json_out);
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["ensemble_min_trials"].get<int>(), 1);
  EXPECT_NEAR(j["mean_diagonal_length_mm"].get<double>(), 0.01 * j["mean_diagonal_length"].get<double>(),
              1e-9);
  for (const auto& t : j["trials"]) EXPECT_NEAR(t["recurrence_rate"].get<double>(), 0.05, 0.0005);
  // Recurring in either trial is at least as frequent as in each.
  EXPECT_GE(j["recurrence_rate"].get<double>(), 0.05);
  const std::string png = dir() + "/rp.png";
  const auto plot = run("signals recurrence-plot " + files[0] + common +
                        "--time-column x_mm --recurrence-rate 0.05 --side-px 200 --out " + png);
  ASSERT_EQ(plot.code, 0) << plot.output;
  EXPECT_GT(std::filesystem::file_size(png), 1000u);
  const std::string emb = dir() + "/embedding.json";
  const auto e = run("signals embedding " + files[0] +
                     " --column height_um --time-column x_mm --max-delay 30 " + "--max-dim 4 --out " + emb);
  ASSERT_EQ(e.code, 0) << e.output;
  std::ifstream ef(emb);
  const auto ej = nlohmann::json::parse(ef);
  // The values themselves are checked against closed forms in recurrence_test.cpp; here the contract.
  EXPECT_EQ(ej["mutual_information_nats"].size(), 31u);
  ASSERT_EQ(ej["false_neighbour_fraction"].size(), 4u);
  EXPECT_GT(ej["false_neighbour_fraction"][0].get<double>(), ej["false_neighbour_fraction"][1].get<double>());
  EXPECT_EQ(ej["fnn_delay"].get<int>(), std::max(1, ej["suggested_delay"].get<int>()));
  const auto bad = run("signals rqa " + files[0] + common + "--joint-recurrence-rate 0.05 --out " + json_out);
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.output.find("--joint-column"), std::string::npos) << bad.output;
}

TEST(SignalsCli, FrictionSpeedAndTextureInteractionWriteTheirContracts) {
  const std::string csv = dir() + "/speeds.csv", out = dir() + "/speed_law.json";
  {
    std::ofstream f(csv);
    f << "speed_m_s,mu\n";
    for (int i = 0; i < 8; ++i) {
      const double v = 0.004 * std::pow(1.8, i);
      f << tirstrain::format_double(v) << ',' << tirstrain::format_double(0.9 - 0.05 * std::log(v / 0.01))
        << '\n';
    }
  }
  const auto r = run("signals friction-speed " + csv + " --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream jf(out);
  const auto j = nlohmann::json::parse(jf);
  EXPECT_NEAR(j["log"]["beta"].get<double>(), -0.05, 1e-9);
  EXPECT_NEAR(j["log"]["mu_ref"].get<double>(), 0.9, 1e-9);
  EXPECT_EQ(j["preferred"], "log");
  const std::string tex = dir() + "/texture.json";
  const auto t = run("model texture-interaction --texture-period-mm 0.2 1.0 --speed-mm-s 50 --out " + tex);
  ASSERT_EQ(t.code, 0) << t.output;
  EXPECT_NE(t.output.find("finer_than_ridges"), std::string::npos) << t.output;
  std::ifstream tf(tex);
  const auto tj = nlohmann::json::parse(tf);
  ASSERT_EQ(tj["predictions"].size(), 2u);
  EXPECT_NEAR(tj["predictions"][1]["surface_frequency_Hz"].get<double>(), 50.0, 1e-9);  // v / λ
  EXPECT_EQ(tj["predictions"][1]["zone"], "coarser_than_ridges");
  const auto bad = run("model texture-interaction --texture-period-mm 0.2 --speed-mm-s -1");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.output.find("--speed-mm-s"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("the speed must be positive and finite"), std::string::npos) << bad.output;
  // A period far below the contact's length is refused at once (it was sampled until memory ran out), and so
  // are a negative tolerance and a line fraction above 1.
  const auto tiny = run("model texture-interaction --texture-period-mm 1e-9");
  EXPECT_EQ(tiny.code, 2) << tiny.output;
  EXPECT_NE(tiny.output.find("the texture period is below 1/10000 of the contact length"), std::string::npos)
      << tiny.output;
  EXPECT_EQ(run("model texture-interaction --texture-period-mm 0.45 --zone-tolerance -1").code, 2);
  EXPECT_EQ(run("model texture-interaction --texture-period-mm 0.45 --min-line-fraction 2").code, 2);
}

TEST(SignalsCli, ImpedanceFromVelocityWithAFixedStiffnessAndANarrowBandWarning) {
  // A mass and a damper (m = 12 g, c = 3.5 N s/m, no spring) driven by a multisine on every analysis bin
  // from 16 to 480 Hz: F = m a + c v exactly, v and a analytic.
  const double fs = 4096.0, m = 0.012, c = 3.5;
  const std::string in = dir() + "/vibrometer.csv";
  {
    std::ofstream f(in);
    f << "t_s,F_N,v_m_s,a_m_s2\n";
    for (int i = 0; i < 16384; ++i) {
      const double t = i / fs;
      double v = 0.0, a = 0.0;
      for (int n = 2; n <= 60; ++n) {
        const double w = 2 * std::numbers::pi * 8.0 * n, phase = 0.7 * n * n;
        v += 0.01 * std::sin(w * t + phase);
        a += 0.01 * w * std::cos(w * t + phase);
      }
      f << tirstrain::format_double(t) << ',' << tirstrain::format_double(m * a + c * v) << ','
        << tirstrain::format_double(v) << ',' << tirstrain::format_double(a) << '\n';
    }
  }
  const std::string z = dir() + "/z.csv", fit = dir() + "/fit.json";
  auto r =
      run("signals impedance " + in + " --force F_N --velocity-column v_m_s --segment 512 --band-Hz 20,450 " +
          "--fix-stiffness 0 --fit-out " + fit + " --out " + z);
  ASSERT_EQ(r.code, 0) << r.output;
  {
    std::ifstream jf(fit);
    const auto j = nlohmann::json::parse(jf);
    EXPECT_NEAR(j["m_kg"].get<double>(), m, 0.01 * m);
    EXPECT_NEAR(j["c_Ns_m"].get<double>(), c, 0.02 * c);
    EXPECT_EQ(j["k_N_m"].get<double>(), 0.0);
    EXPECT_TRUE(j["stiffness_fixed"].get<bool>());
    EXPECT_TRUE(j["warnings"].empty());
  }
  // Acceleration over 200-240 Hz with k free: the band cannot tell k from m, and the JSON says so.
  r = run("signals impedance " + in +
          " --force F_N --accel a_m_s2 --segment 512 --band-Hz 200,240 --fit-out " + fit + " --out " + z +
          " 2>&1");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream jf(fit);
  const auto j = nlohmann::json::parse(jf);
  EXPECT_GT(std::abs(j["m_k_correlation"].get<double>()), 0.95);
  ASSERT_EQ(j["warnings"].size(), 1u);
  EXPECT_NE(r.output.find("--fix-stiffness"), std::string::npos) << r.output;
  r = run("signals impedance " + in + " --force F_N --segment 512 --out " + z);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--velocity-column"), std::string::npos) << r.output;
}

// A side accelerometer reading half the pad's acceleration at every frequency (G1 = 0.5), a 10 µm pad
// vibration at 50 Hz, and the force a known spring-mass-damper needs for it: both routes give the pad's
// displacement back, 10 µm / sqrt(2) RMS in the band around 50 Hz.
TEST(SignalsCli, PadDeformationRecoversTheDisplacementByBothRoutes) {
  const double fs = 1000.0, x_m = 1e-5, w = 2 * std::numbers::pi * 50.0;
  const double m = 0.01, c = 1.0, k = 5000.0;
  const std::string calibration = dir() + "/pad_calibration.csv", trial = dir() + "/pad_trial.csv";
  {
    std::ofstream cal(calibration), tr(trial);
    cal << "t_s,pad_m_s2,side_m_s2\n";
    tr << "t_s,side_m_s2,F_N\n";
    for (int i = 0; i < 8000; ++i) {
      const double t = i / fs;
      double pad = 0.0;
      for (int n = 1; n <= 45; ++n) pad += std::sin(2 * std::numbers::pi * 10.0 * n * t + 0.7 * n * n);
      cal << tirstrain::format_double(t) << ',' << tirstrain::format_double(pad) << ','
          << tirstrain::format_double(0.5 * pad) << '\n';
      const double pad_accel = -w * w * x_m * std::sin(w * t);
      const double force = (k - m * w * w) * x_m * std::sin(w * t) + c * w * x_m * std::cos(w * t);
      tr << tirstrain::format_double(t) << ',' << tirstrain::format_double(0.5 * pad_accel) << ','
         << tirstrain::format_double(force) << '\n';
    }
  }
  const std::string out = dir() + "/pad.csv", bands = dir() + "/pad_bands.csv";
  const auto r = run("signals pad-deformation " + trial + " --calibration " + calibration +
                     " --cal-pad pad_m_s2 --cal-side side_m_s2 --side side_m_s2 --force F_N --m-kg 0.01 "
                     "--c-Ns-m 1 --k-N-m 5000 --segment 1000 --bands-Hz 40,60 --bands-out " +
                     bands + " --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto spectrum = tirstrain::read_numeric_csv(out);
  const auto& gain = spectrum.column("g1_gain");
  const auto& freq = spectrum.column("freq_Hz");
  for (std::size_t i = 0; i < freq.size(); ++i) {
    if (std::abs(std::fmod(freq[i] + 5.0, 10.0) - 5.0) < 0.5 && freq[i] > 5.0 && freq[i] < 455.0) {
      EXPECT_NEAR(gain[i], 0.5, 1e-6) << freq[i] << " Hz";  // a calibration tone's bin
    }
  }
  const auto band = tirstrain::read_numeric_csv(bands);
  ASSERT_EQ(band.column("rms_side_m").size(), 1u);
  EXPECT_NEAR(band.column("rms_side_m")[0], x_m / std::sqrt(2.0), 0.03 * x_m / std::sqrt(2.0));
  EXPECT_NEAR(band.column("rms_force_m")[0], x_m / std::sqrt(2.0), 0.03 * x_m / std::sqrt(2.0));
  EXPECT_NEAR(band.column("ratio")[0], 1.0, 0.03);
  const auto refused =
      run("signals pad-deformation " + trial + " --calibration " + calibration +
          " --cal-pad pad_m_s2 --cal-side side_m_s2 --side side_m_s2 --force F_N --segment 1000 "
          "--out " +
          out);
  EXPECT_EQ(refused.code, 2);
  EXPECT_NE(refused.output.find("--m-kg"), std::string::npos) << refused.output;
}

TEST(SignalsCli, BadInputIsLocated) {
  const std::string bad = dir() + "/bad.csv";
  std::ofstream(bad) << "t_s,force_N\n0,1\n0.001,2\n0.001,3\n0.003,4\n";
  auto r = run("signals psd " + bad + " --column force_N --segment 2 --out " + dir() + "/x.csv");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("row 4"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("duplicate"), std::string::npos);
  r = run("signals filter " + write_trial() + " --column nope --lowpass-Hz 80 --out " + dir() + "/x.csv");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("column 'nope'"), std::string::npos);
  r = run("signals filter " + write_trial() + " --column force_N --lowpass-Hz 800 --out " + dir() + "/x.csv");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("--lowpass-Hz"), std::string::npos);
  EXPECT_NE(r.output.find("Nyquist"), std::string::npos);
  r = run("signals filter " + write_trial() + " --column force_N --lowpass-Hz 80 --highpass-Hz 5 --out " +
          dir() + "/x.csv");
  EXPECT_EQ(r.code, 2);  // the command line is wrong
  EXPECT_FALSE(std::filesystem::exists(dir() + "/x.csv"));
  r = run("signals rqa " + write_trial() + " --column force_N --dim 3 --delay 2 --threshold -1 --out " +
          dir() + "/x.json");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--threshold"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("must be a number of 0 or more"), std::string::npos) << r.output;
}

TEST(SignalsCli, FrictionAndPowerLaw) {
  // W = 2 N; plate still until 0.5 s, then 10 mm/s; F_t follows the Cattaneo–Mindlin curve to μW = 1.6 N.
  const std::string in = dir() + "/friction.csv";
  {
    std::ofstream out(in);
    out << "t_s,normal_N,tangential_N,position_m\n";
    for (int i = 0; i <= 2000; ++i) {
      const SlideSample x = slide_at(i);
      out << tirstrain::format_double(x.t_s) << ",2," << tirstrain::format_double(x.tangential_N) << ','
          << tirstrain::format_double(x.slide_m) << '\n';
    }
  }
  const std::string mu = dir() + "/mu.csv", summary = dir() + "/friction.json";
  auto r = run("signals friction " + in +
               " --tangential tangential_N --normal normal_N --position position_m --out " + mu +
               " --summary " + summary);
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream f(summary);
  const auto j = nlohmann::json::parse(f);
  // μ over the whole slide, from where the rise's slope falls to 20 % of its steepest (96 % of the slip
  // distance, F_t within 0.8 % of μW there): the tail of the rise lowers the mean by about 2e-5.
  EXPECT_NEAR(j["mu_dynamic"].get<double>(), 0.8, 1e-4);
  EXPECT_LT(j["mu_dynamic"].get<double>(), 0.8);
  EXPECT_NEAR(j["onset_s"].get<double>(), 0.5, 1e-3);
  EXPECT_NEAR(j["t90_s"].get<double>(), 0.5 + (1 - std::pow(0.1, 2.0 / 3.0)) * 0.2, 1e-3);
  EXPECT_TRUE(j.contains("external_work_J"));
  const std::string trials = dir() + "/trials.csv", fit = dir() + "/fit.json";
  {
    std::ofstream out(trials);
    out << "normal_N,mu\n";
    for (int i = 0; i < 20; ++i) {
      const double w = 0.2 + 0.25 * i;
      out << w << ',' << tirstrain::format_double(1.63 * std::pow(w, -0.33) * (1 + 0.01 * ((i % 3) - 1)))
          << '\n';
    }
  }
  r = run("signals power-law " + trials + " --out " + fit);
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream g(fit);
  const auto k = nlohmann::json::parse(g);
  EXPECT_NEAR(k["a"].get<double>(), 1.63, 0.02 * 1.63);
  EXPECT_NEAR(k["b"].get<double>(), -0.33, 0.02);
  EXPECT_LT(k["b_low"].get<double>(), k["b"].get<double>());
}

// The friction recording above with its columns in other units: position in mm (or with no unit in the name),
// the forces in mN, and the position counted the other way; U_ext in closed form (slide_external_work_J).
TEST(SignalsCli, FrictionReadsTheUnitsInTheColumnNames) {
  const std::string in = dir() + "/friction_units.csv";
  {
    std::ofstream out(in);
    out << "t_s,normal_mN,tangential_mN,x_mm,x_back_mm,x\n";
    for (int i = 0; i <= 2000; ++i) {
      const SlideSample x = slide_at(i);
      out << tirstrain::format_double(x.t_s) << ",2000," << tirstrain::format_double(1e3 * x.tangential_N)
          << ',' << tirstrain::format_double(1e3 * x.slide_m) << ','
          << tirstrain::format_double(-1e3 * x.slide_m) << ',' << tirstrain::format_double(1e3 * x.slide_m)
          << '\n';
    }
  }
  const double work_J = slide_external_work_J();
  const auto summary_of = [&](const std::string& position) {
    const std::string summary = dir() + "/friction_units.json";
    const auto r = run("signals friction " + in + " --tangential tangential_mN --normal normal_mN " +
                       position + " --out " + dir() + "/mu_units.csv --summary " + summary);
    EXPECT_EQ(r.code, 0) << r.output;
    std::ifstream f(summary);
    return nlohmann::json::parse(f);
  };
  const auto warned = [](const nlohmann::json& j, const std::string& code) {
    for (const auto& w : j["warnings"])
      if (w["code"] == code) return true;
    return false;
  };
  auto j = summary_of("--position x_mm");
  EXPECT_NEAR(j["external_work_J"].get<double>(), work_J, 0.01 * work_J);
  EXPECT_NEAR(j["mu_dynamic"].get<double>(), 0.8, 1e-4);
  EXPECT_NEAR(j["plateau_tangential_N"].get<double>(), 1.6, 0.01);
  EXPECT_FALSE(warned(j, "external_work_negative"));
  j = summary_of("--position x --position-unit mm");
  EXPECT_NEAR(j["external_work_J"].get<double>(), work_J, 0.01 * work_J);
  j = summary_of("--position x");  // no unit known: the onset still, U_ext not
  EXPECT_NEAR(j["onset_s"].get<double>(), 0.5, 1e-3);
  EXPECT_FALSE(j.contains("external_work_J"));
  EXPECT_TRUE(warned(j, "external_work_not_measured"));
  j = summary_of("--position x_back_mm");
  EXPECT_NEAR(j["external_work_J"].get<double>(), -work_J, 0.01 * work_J);
  EXPECT_TRUE(warned(j, "external_work_negative"));
  const auto r =
      run("signals friction " + in + " --tangential tangential_mN --normal normal_mN --position x " +
          "--position-unit inch --out " + dir() + "/mu_units.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("--position-unit"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("m, mm, um"), std::string::npos) << r.output;
}

// The same recording as a spreadsheet or DAQ program writes it: units in brackets, time in ms. Read in
// those units (plateau 1.6 N, U_ext in closed form); a force unit not known here is refused, not read as N.
TEST(SignalsCli, FrictionReadsBracketedUnits) {
  const std::string in = dir() + "/friction_brackets.csv";
  {
    std::ofstream out(in);
    out << "t [ms],Fz [mN],Fx (mN),x [mm],Fy [kN]\n";
    for (int i = 0; i <= 2000; ++i) {
      const SlideSample x = slide_at(i);
      out << i << ",2000," << tirstrain::format_double(1e3 * x.tangential_N) << ','
          << tirstrain::format_double(1e3 * x.slide_m) << ",0.001\n";
    }
  }
  const double work_J = slide_external_work_J();
  const std::string summary = dir() + "/friction_brackets.json", mu = dir() + "/mu_brackets.csv";
  auto r =
      run("signals friction " + in + " --time-column 't [ms]' --tangential 'Fx (mN)' --normal 'Fz [mN]' " +
          "--position 'x [mm]' --out " + mu + " --summary " + summary);
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream f(summary);
  const auto j = nlohmann::json::parse(f);
  EXPECT_NEAR(j["plateau_tangential_N"].get<double>(), 1.6, 0.01);
  EXPECT_NEAR(j["mu_dynamic"].get<double>(), 0.8, 1e-4);
  EXPECT_NEAR(j["onset_s"].get<double>(), 0.5, 1e-3);
  EXPECT_NEAR(j["external_work_J"].get<double>(), work_J, 0.01 * work_J);
  EXPECT_EQ(tirstrain::read_numeric_csv(mu).names[0], "t [s]");
  r = run("signals friction " + in + " --time-column 't [ms]' --tangential 'Fy [kN]' --normal 'Fz [mN]' " +
          "--out " + mu);
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("cannot tell the unit of column 'Fy [kN]'"), std::string::npos) << r.output;
}

// A 0.5 mm grating felt at 10 mm/s, the position recorded in mm: the spectrum's peak is at λ = 0.5e-3 m
// (within the 512-sample segment's resolution, 2.5 %), and a position without a unit is refused.
TEST(SignalsCli, SpatialReadsThePositionsUnit) {
  const std::string in = dir() + "/grating.csv";
  {
    std::ofstream out(in);
    out << "t_s,force_N,x_mm,x\n";
    for (int i = 0; i < 2000; ++i) {
      const double t = i / 1000.0, x_mm = 10.0 * t;
      out << tirstrain::format_double(t) << ','
          << tirstrain::format_double(1 + 0.1 * std::sin(2 * std::numbers::pi * x_mm / 0.5)) << ','
          << tirstrain::format_double(x_mm) << ',' << tirstrain::format_double(x_mm) << '\n';
    }
  }
  const std::string out = dir() + "/grating_spectrum.csv";
  auto r = run("signals spatial " + in + " --force force_N --position x_mm --segment 512 --out " + out);
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream csv(out);
  std::string line;
  std::getline(csv, line);
  double best_psd = -1.0, best_wavelength_m = 0.0;
  while (std::getline(csv, line)) {
    std::stringstream cells(line);
    std::string freq, wavelength, psd;
    std::getline(cells, freq, ',');
    std::getline(cells, wavelength, ',');
    std::getline(cells, psd, ',');
    if (std::stod(psd) > best_psd) {
      best_psd = std::stod(psd);
      best_wavelength_m = std::stod(wavelength);
    }
  }
  EXPECT_NEAR(best_wavelength_m, 0.5e-3, 0.025 * 0.5e-3);
  r = run("signals spatial " + in + " --force force_N --position x --segment 512 --out " + out + "2");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("cannot tell the unit of position column 'x'"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(out + "2"));
}

TEST(SignalsCli, AlignThreeModes) {
  // Channel clock: plate at rest until 0.2 s then 5 mm/s; a trigger with a 4 ms linear rise whose 2.5 V point
  // is at 0.302 s. Camera: 100 fps from 0.05 s on a clock 23.37 ms ahead, plate in pixels along -x (52
  // px/mm), so the camera series falls while the position rises: align orients both before correlating.
  const double offset = 0.02337;
  const auto plate_m = [](double t) { return t > 0.2 ? 5e-3 * (t - 0.2) : 0.0; };
  const std::string in = dir() + "/align.csv", camera = dir() + "/camera.csv";
  {
    std::ofstream out(in);
    out << "t_s,position_m,trigger_V\n";
    for (int i = 0; i <= 1200; ++i) {
      const double t = i / 1000.0;
      out << tirstrain::format_double(t) << ',' << tirstrain::format_double(plate_m(t)) << ','
          << tirstrain::format_double(5.0 * std::clamp((t - 0.3) / 0.004, 0.0, 1.0)) << '\n';
    }
    std::ofstream cam(camera);
    cam << "t_s,plate_px\n";
    for (int k = 0; k < 100; ++k) {
      const double t = 0.05 + 0.01 * k;
      cam << tirstrain::format_double(t) << ',' << tirstrain::format_double(-52000.0 * plate_m(t - offset))
          << '\n';
    }
  }
  const std::string json_out = dir() + "/align.json", shifted = dir() + "/shifted.csv";
  const auto read = [&] {
    std::ifstream f(json_out);
    return nlohmann::json::parse(f);
  };
  auto r = run("signals align " + in + " --offset-s 0.0125 --shifted-out " + shifted + " --out " + json_out);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(read()["method"], "explicit");
  EXPECT_DOUBLE_EQ(read()["offset_s"].get<double>(), 0.0125);
  const auto moved = tirstrain::read_numeric_csv(shifted);
  EXPECT_EQ(moved.names, (std::vector<std::string>{"t_s", "position_m", "trigger_V"}));
  EXPECT_NEAR(moved.column("t_s")[1000], 1.0125, 1e-12);
  EXPECT_DOUBLE_EQ(moved.column("position_m")[1000], plate_m(1.0));

  r = run("signals align " + in + " --trigger trigger_V --camera-edge-s 0.5 --out " + json_out);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(read()["method"], "trigger");
  EXPECT_NEAR(read()["channel_edge_s"].get<double>(), 0.302, 1e-12);
  EXPECT_NEAR(read()["offset_s"].get<double>(), 0.198, 1e-12);

  r = run("signals align " + in + " --position position_m --camera " + camera +
          " --camera-column plate_px --max-lag-s 0.1 --out " + json_out);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto j = read();
  std::printf("[ measured ] align cross-correlation: offset error %.3g s\n",
              j["offset_s"].get<double>() - offset);
  EXPECT_EQ(j["method"], "cross-correlation");
  EXPECT_NEAR(j["offset_s"].get<double>(), offset, 1e-5);  // 1 % of a channel sample
  EXPECT_EQ(j["camera_samples_compared"].get<int>(), 100);

  // Two modes at once, a missing column, a trigger that never crosses its threshold.
  r = run("signals align " + in + " --offset-s 0.1 --trigger trigger_V --camera-edge-s 0 --out " + json_out);
  EXPECT_NE(r.code, 0);
  r = run("signals align " + in + " --trigger nope --camera-edge-s 0 --out " + json_out);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("column 'nope'"), std::string::npos) << r.output;
  r = run("signals align " + in + " --trigger trigger_V --threshold 7 --camera-edge-s 0 --out " + json_out);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("align.csv"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("never crosses"), std::string::npos) << r.output;
}
