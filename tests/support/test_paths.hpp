// Where the test binary finds the things the build made for it.
#pragma once

#include <filesystem>
#include <string>

namespace talus::test {

inline std::filesystem::path fixture(const std::string &name) {
    return std::filesystem::path(TALUS_TEST_FIXTURE_DIR) / ("fixture_" + name + ".so");
}
inline std::filesystem::path fixture_dir() { return TALUS_TEST_FIXTURE_DIR; }
inline std::filesystem::path plugin_dir() { return TALUS_TEST_PLUGIN_DIR; }
inline std::filesystem::path source_dir() { return TALUS_TEST_SOURCE_DIR; }
inline std::filesystem::path data_dir() { return TALUS_TEST_DATA_DIR; }

// gtest's EXPECT_THAT needs gmock; a substring check reads as well.
inline bool contains(const std::string &text, const std::string &part) {
    return text.find(part) != std::string::npos;
}

} // namespace talus::test
