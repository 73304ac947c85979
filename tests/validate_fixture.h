// Shared by the tests of the validation suite (validate_test.cpp) and of `eco validate`
// (validate_cli_test.cpp): reading its report and results.csv, and a minimal scenario
// configuration.
#pragma once

#include "test_util.h"

#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace eco::test {


/// Rows of results.csv as (scenario/check) -> (value, pass).
inline std::map<std::string, std::pair<std::string, std::string>> readResults(const std::string& path) {
    std::map<std::string, std::pair<std::string, std::string>> out;
    std::ifstream in(path);
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
        std::vector<std::string> f;
        std::string cur;
        bool quoted = false;
        for (char c : line) {
            if (c == '"') quoted = !quoted;
            else if (c == ',' && !quoted) {
                f.push_back(cur);
                cur.clear();
            } else cur += c;
        }
        f.push_back(cur);
        if (f.size() >= 9) out[f[1] + "/" + f[2]] = {f[3], f[8]};
    }
    return out;
}

inline const char* const kMinimalCircles = R"(
[scenario]
name = "circles_small"
kind = "deussen_circles"
title = "t"
description = "d"

[circles]
initial_radius_min_m = 0.01
initial_radius_max_m = 0.10
growth_per_step_m = 0.01
limit_radius_m = 3.0
max_steps = 400
onset_killed_fraction = 0.2
min_plants_in_fit = 100

[quick]
plant_count = 4000
field_side_m = 63.0
seed = 1

[full]
plant_count = 4000
field_side_m = 63.0
seed = 1

[checks.slope]
expected = -1.0
tolerance = 0.2

[checks.r_squared]
min = 0.9
)";

}  // namespace eco::test
