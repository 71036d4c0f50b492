#pragma once
// One named spdlog logger per module: cslam::logger("tracking")->info(...).
// Pure maths code logs nothing; it returns result structs instead.
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

namespace cslam {

// Returns the logger with this name, creating it (stderr, shared level) on first use.
std::shared_ptr<spdlog::logger> logger(const std::string& name);

// Sets the level of every cslam logger: trace, debug, info, warn, error, off.
// Throws ConfigError on an unknown level name.
void set_log_level(const std::string& level);

}  // namespace cslam
