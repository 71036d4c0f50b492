#pragma once
// Errors: bad input data (files, packets) is reported with an InputError naming its source,
// programming and configuration errors throw ConfigError / std::logic_error.
#include <stdexcept>
#include <string>

namespace cslam {

// Bad input from outside (a file, a line, a packet). what() is one line naming the source.
class InputError : public std::runtime_error {
 public:
  InputError(const std::string& source, const std::string& message);
  InputError(const std::string& source, int line, const std::string& message);
  const std::string& source() const { return source_; }
  int line() const { return line_; }

 private:
  std::string source_;
  int line_ = 0;
};

// A configuration value that is missing, unknown or out of range.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace cslam
