#include "core/error.h"

namespace cslam {

InputError::InputError(const std::string& source, const std::string& message)
    : std::runtime_error(source + ": " + message), source_(source) {}

InputError::InputError(const std::string& source, int line, const std::string& message)
    : std::runtime_error(source + ":" + std::to_string(line) + ": " + message), source_(source), line_(line) {}

}  // namespace cslam
