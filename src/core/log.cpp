#include "core/log.h"

#include <spdlog/sinks/stdout_color_sinks.h>

#include "core/error.h"

namespace cslam {

std::shared_ptr<spdlog::logger> logger(const std::string& name) {
  if (auto existing = spdlog::get(name)) return existing;
  try {
    auto created = spdlog::stderr_color_mt(name);
    created->set_level(spdlog::get_level());
    created->set_pattern("[%H:%M:%S.%e] [%n] [%^%l%$] %v");
    return created;
  } catch (const spdlog::spdlog_ex&) {
    // Another thread registered it between get() and create().
    return spdlog::get(name);
  }
}

void set_log_level(const std::string& level) {
  auto parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    throw ConfigError("unknown log level '" + level + "' (use trace, debug, info, warn, error, off)");
  }
  spdlog::set_level(parsed);
  spdlog::apply_all([parsed](std::shared_ptr<spdlog::logger> l) { l->set_level(parsed); });
}

}  // namespace cslam
