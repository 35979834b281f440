// The YAML front end's error reporting: locations, unknown keys with
// suggestions, duplicate keys, types.
#include "test_paths.hpp"

#include <talus/input/yaml_input.hpp>

#include <gtest/gtest.h>

#include <array>

using talus::test::contains;
namespace ty = talus::yaml;

namespace {
std::string error_of(const std::function<void()> &f) {
    try {
        f();
    } catch (const talus::Error &e) {
        return e.what();
    }
    return "(no error)";
}
} // namespace

TEST(YamlInput, ClosestMatchFindsTyposOnly) {
    constexpr std::array<std::string_view, 4> keys = {"youngs_modulus", "poisson_ratio", "density",
                                                      "model"};
    EXPECT_EQ(ty::closest_match("yongs_modulus", keys), "youngs_modulus"); // deletion
    EXPECT_EQ(ty::closest_match("poisson_ration", keys), "poisson_ratio"); // insertion
    EXPECT_EQ(ty::closest_match("desnity", keys), "density");              // transposition
    EXPECT_EQ(ty::closest_match("modle", keys), "model");
    EXPECT_EQ(ty::closest_match("friction_angle", keys), ""); // nothing close: no guess
}

TEST(YamlInput, UnknownKeyNamesLineColumnAndSuggestion) {
    const ty::Node root = ty::load_string("a: 1\nmaterial:\n  dencity: 3\n", "case.yaml");
    constexpr std::array<std::string_view, 2> allowed = {"density", "model"};
    const std::string msg = error_of([&] { root.get("material").allow_keys(allowed); });
    EXPECT_TRUE(contains(msg, "case.yaml:3:3: error: unknown key 'material.dencity'; did you mean "
                              "'density'?"))
        << msg;
}

TEST(YamlInput, DuplicateKeyIsAnError) {
    const ty::Node root = ty::load_string("x: 1\ny: 2\nx: 3\n", "dup.yaml");
    constexpr std::array<std::string_view, 2> allowed = {"x", "y"};
    const std::string msg = error_of([&] { root.allow_keys(allowed); });
    EXPECT_TRUE(contains(msg, "dup.yaml:3:1: error: 'x' is given twice (first at dup.yaml:1:1)"))
        << msg;
}

TEST(YamlInput, TypeErrorsSayWhatWasExpected) {
    const ty::Node root = ty::load_string("e: abc\nn: 2.5\nf: .nan\nb: maybe\n", "t.yaml");
    EXPECT_TRUE(contains(error_of([&] { root.get("e").as_double(); }),
                         "t.yaml:1:4: error: 'e' expected a number, got 'abc'"));
    EXPECT_TRUE(
        contains(error_of([&] { root.get("n").as_integer(); }), "expected an integer, got '2.5'"));
    EXPECT_TRUE(contains(error_of([&] { root.get("f").as_double(); }), "expected a finite number"));
    EXPECT_TRUE(contains(error_of([&] { root.get("b").as_bool(); }), "expected true or false"));
}

TEST(YamlInput, MissingKeyAndSyntaxError) {
    const ty::Node root = ty::load_string("time:\n  end: 1\n", "m.yaml");
    EXPECT_TRUE(contains(error_of([&] { root.get("time").require("increments"); }),
                         "m.yaml:2:3: error: missing required key 'time.increments'"));
    EXPECT_TRUE(
        contains(error_of([] { ty::load_string("a: [1, 2\nb: 3\n", "s.yaml"); }), "s.yaml:"));
    EXPECT_TRUE(contains(error_of([] { ty::load_string("", "e.yaml"); }),
                         "e.yaml: error: the file is empty"));
    EXPECT_TRUE(
        contains(error_of([] { ty::load_file("/nonexistent/x.yaml"); }), "cannot open file"));
}
