#include <gtest/gtest.h>

#include <fstream>
#include <functional>

#include "core/error.hpp"
#include "core/scene.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain {
namespace {

std::string write_scene(const std::string& name, const std::string& text) {
  const std::string path = std::string(TIRSTRAIN_TEST_TMP) + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string testing_error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

std::string error_of(const std::string& path) {
  try {
    load_scene(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Scene, DefaultsWhenSectionsAreAbsent) {
  const Scene s = load_scene(write_scene("empty.yaml", "{}\n"));
  EXPECT_DOUBLE_EQ(s.px_per_mm, 52.0);
  EXPECT_DOUBLE_EQ(s.tissue.young_Pa, 1.0e6);
  EXPECT_DOUBLE_EQ(s.tissue.poisson, 0.4);
  EXPECT_DOUBLE_EQ(s.tissue.depth_m, 0.002);
  EXPECT_FALSE(s.ridge_period_mm.has_value());
  EXPECT_EQ(s.compute, std::vector<std::string>{"contact"});
  // What the file leaves out is marked, so `process` can pick the stages and say which values are defaults.
  EXPECT_FALSE(s.compute_given);
  EXPECT_FALSE(s.px_per_mm_given);
  EXPECT_FALSE(s.tissue_given);
  EXPECT_TRUE(s.reference_pattern_detect);
  // Saved back without a compute list, it still has none.
  const std::string copy = std::string(TIRSTRAIN_TEST_TMP) + "/empty_copy.yaml";
  save_scene(s, copy);
  EXPECT_FALSE(load_scene(copy).compute_given);
}

TEST(Scene, ReadsValuesAndRoundTrips) {
  const std::string path =
      write_scene("full.yaml",
                  "calibration: {px_per_mm: 40.5, ridge_period_mm: 0.5, ridge_polarity: dark}\n"
                  "tissue: {E_Pa: 2.0e5, nu: 0.45, depth_m: 0.003}\n"
                  "reference_pattern: {roi_px: [0, 400, 640, 100]}\n"
                  "compute: [contact, tracking]\n"
                  "synthesis: {frames: 10}\n");
  const Scene s = load_scene(path);
  EXPECT_DOUBLE_EQ(s.px_per_mm, 40.5);
  EXPECT_DOUBLE_EQ(*s.ridge_period_mm, 0.5);
  EXPECT_EQ(s.ridge_polarity, "dark");
  EXPECT_DOUBLE_EQ(s.tissue.poisson, 0.45);
  ASSERT_TRUE(s.reference_pattern_roi);
  EXPECT_EQ(s.reference_pattern_roi->y, 400);
  EXPECT_EQ(s.compute.size(), 2u);
  EXPECT_TRUE(s.compute_given);
  EXPECT_TRUE(s.px_per_mm_given);
  EXPECT_TRUE(s.tissue_given);
  EXPECT_EQ(YamlSection(s.synthesis, s.file, "synthesis").integer("frames", -1), 10);

  const std::string copy = std::string(TIRSTRAIN_TEST_TMP) + "/copy.yaml";
  save_scene(s, copy);
  const Scene t = load_scene(copy);
  EXPECT_DOUBLE_EQ(t.px_per_mm, 40.5);
  EXPECT_DOUBLE_EQ(t.tissue.young_Pa, 2.0e5);
  EXPECT_EQ(t.reference_pattern_roi->height, 100);
  EXPECT_EQ(t.compute, s.compute);
  EXPECT_TRUE(t.compute_given);
}

TEST(Scene, PatternDetectionCanBeTurnedOff) {
  const Scene s = load_scene(write_scene("nodetect.yaml", "reference_pattern: {detect: false}\n"));
  EXPECT_FALSE(s.reference_pattern_detect);
  EXPECT_FALSE(s.reference_pattern_roi.has_value());
  const std::string copy = std::string(TIRSTRAIN_TEST_TMP) + "/nodetect_copy.yaml";
  save_scene(s, copy);
  EXPECT_FALSE(load_scene(copy).reference_pattern_detect);
}

TEST(Scene, BadFilesNameTheKeyAndFile) {
  const auto unknown = write_scene("unknown.yaml", "tissue: {E_Pa: 1e6, poisson: 0.3}\n");
  const std::string m1 = error_of(unknown);
  EXPECT_NE(m1.find(unknown), std::string::npos);
  EXPECT_NE(m1.find("'tissue.poisson': unknown key"), std::string::npos) << m1;
  EXPECT_NE(
      error_of(write_scene("type.yaml", "tissue: {E_Pa: soft}\n")).find("'tissue.E_Pa': expected a number"),
      std::string::npos);
  EXPECT_NE(
      error_of(write_scene("range.yaml", "tissue: {nu: 0.7}\n")).find("'tissue.nu': value 0.7 is outside"),
      std::string::npos);
  EXPECT_NE(error_of(write_scene("top.yaml", "calibraton: {}\n")).find("'calibraton': unknown key"),
            std::string::npos);
  EXPECT_NE(error_of(write_scene("stage.yaml", "compute: [contact, magic]\n")).find("unknown stage 'magic'"),
            std::string::npos);
  EXPECT_NE(error_of(write_scene("syntax.yaml", "tissue: {E_Pa: [1, 2\n")).find("not valid YAML"),
            std::string::npos);
  EXPECT_NE(error_of(write_scene("choice.yaml", "calibration: {ridge_polarity: grey}\n"))
                .find("'grey' is not one of: auto, dark, bright"),
            std::string::npos);
  EXPECT_NE(error_of(std::string(TIRSTRAIN_TEST_TMP) + "/nope.yaml").find("file not found"),
            std::string::npos);
}

TEST(SceneSection, EditsAreCopiesAndRoundTripThroughText) {
  const SceneSection original = SceneSection::parse("{a: 1, b: {c: x}}", "inline.yaml");
  EXPECT_FALSE(original.empty());
  EXPECT_TRUE(original.is_map());
  EXPECT_TRUE(SceneSection().empty());
  EXPECT_TRUE(original.at("missing").empty());
  // A text value is taken as it is: a path with YAML's special characters stays one string.
  const SceneSection edited = original.with("b", original.at("b").with("c", "/data/run: 1 #2"));
  YamlSection before(original, "inline.yaml");
  YamlSection after(SceneSection::parse(edited.to_yaml()), "inline.yaml");
  EXPECT_EQ(before.section("b").text("c", ""), "x");  // the original is unchanged
  EXPECT_EQ(after.section("b").text("c", ""), "/data/run: 1 #2");
  EXPECT_EQ(after.integer("a", 0), 1);
  // An absent section becomes a map when edited.
  YamlSection built(SceneSection().with("k", "v"), "built");
  EXPECT_EQ(built.text("k", ""), "v");
  EXPECT_EQ(SceneSection().to_yaml(), "");
}

TEST(YamlSection, ListsAndMapsKeepTheFilesOrderAndLines) {
  YamlSection s(SceneSection::parse("names: [b, a]\n"
                                    "items:\n"
                                    "  - {n: 1}\n"
                                    "  - {n: 2}\n"
                                    "pairs: {z: 1, y: two}\n"
                                    "nested: [a, [b]]\n"),
                "lists.yaml");
  EXPECT_EQ(s.texts("names"), (std::vector<std::string>{"b", "a"}));
  EXPECT_EQ(s.texts("absent", {"x"}), std::vector<std::string>{"x"});
  std::vector<YamlSection> items = s.sections("items");
  ASSERT_EQ(items.size(), 2u);
  EXPECT_EQ(items[1].integer("n", 0), 2);
  EXPECT_EQ(items[1].line(), 4);
  EXPECT_EQ(items[1].path_of("n"), "items[1].n");
  const auto pairs = s.text_map("pairs");
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].first, "z");
  EXPECT_EQ(pairs[1].second, "two");
  const std::string message = testing_error_of([&] { s.texts("nested", {}, "names"); });
  EXPECT_NE(message.find("lists.yaml: row 6: 'nested': expected a list of names"), std::string::npos)
      << message;
  EXPECT_EQ(s.keys(), (std::vector<std::string>{"names", "items", "pairs", "nested"}));
  EXPECT_NO_THROW(s.finish());
}

TEST(YamlSection, RequiredAndIntegerChecks) {
  YamlSection s(SceneSection::parse("{n: 2.5, k: 3}"), "f.yaml", "sec");
  EXPECT_THROW(s.integer("n", 0), Error);
  EXPECT_EQ(s.integer("k", 0, 1, 5), 3);
  try {
    s.required_number("missing");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "f.yaml: 'sec.missing': required key is missing");
  }
}

// Found by fuzz_scene_yaml (tests/fuzz/corpus): a mapping used as a key makes yaml-cpp throw its bad
// conversion, a message without file or line, unless the key is checked first.
TEST(Scene, KeyThatIsNotTextIsRefusedWithItsLine) {
  const std::string message = error_of(write_scene("map_key.yaml", "calibration:\n  {px_per_mm}: 52\n"));
  EXPECT_NE(message.find("map_key.yaml: row 2: 'calibration': a key must be plain text"), std::string::npos)
      << message;
  // YAML text given in code is checked the same way when parsed.
  const std::string parsed = testing_error_of([] { SceneSection::parse("{[a, b]: 1}", "inline.yaml"); });
  EXPECT_NE(parsed.find("inline.yaml: row 1: '(top)': a key must be plain text"), std::string::npos)
      << parsed;
}

TEST(Scene, StageNameThatIsNotTextIsRefusedWithItsLine) {
  // yaml-cpp's own conversion error would escape without the file, key or line.
  const std::string message =
      error_of(write_scene("map_stage.yaml", "calibration: {px_per_mm: 52}\ncompute: [contact, {mm: 5}]\n"));
  EXPECT_NE(message.find("map_stage.yaml"), std::string::npos) << message;
  EXPECT_NE(message.find("compute"), std::string::npos) << message;
  EXPECT_NE(message.find("row 2: 'compute': expected a list of stage names"), std::string::npos) << message;
  const std::string empty = error_of(write_scene("empty_stages.yaml", "compute:\n"));
  EXPECT_NE(empty.find("'compute': expected a list of stage names"), std::string::npos) << empty;
}

TEST(Scene, KeyGivenTwiceIsRefusedWithBothLines) {
  // yaml-cpp would keep both and a lookup would find the first: the second calibration would be ignored.
  const std::string top = write_scene("twice.yaml",
                                      "calibration:\n  px_per_mm: 52\ntissue:\n  E_Pa: 1.0e6\n"
                                      "calibration:\n  px_per_mm: 40\n");
  const std::string message = error_of(top);
  EXPECT_NE(message.find("twice.yaml"), std::string::npos) << message;
  EXPECT_NE(message.find("row 5"), std::string::npos) << message;
  EXPECT_NE(message.find("'calibration'"), std::string::npos) << message;
  EXPECT_NE(message.find("given twice (first at line 1)"), std::string::npos) << message;
  const std::string nested =
      error_of(write_scene("twice_nested.yaml", "tissue:\n  E_Pa: 1.0e6\n  nu: 0.4\n  E_Pa: 2.0e6\n"));
  EXPECT_NE(nested.find("'tissue.E_Pa'"), std::string::npos) << nested;
  EXPECT_NE(nested.find("row 4"), std::string::npos) << nested;
}

}  // namespace
}  // namespace tirstrain
