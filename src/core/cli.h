#pragma once
// A small command-line parser shared by every cslam program: declared options only (an unknown
// option is an error), --help text generated from the declarations, positional arguments kept.
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace cslam {

class CliArgs {
 public:
  CliArgs(std::string program, std::string summary);

  // Declares --name VALUE (with a default, or required if default is nullopt) or a --flag.
  CliArgs& option(const std::string& name, const std::string& help,
                  std::optional<std::string> default_value = std::nullopt);
  CliArgs& multi_option(const std::string& name, const std::string& help);  // --name V1 V2 ... (until next --)
  CliArgs& flag(const std::string& name, const std::string& help);
  CliArgs& positional(const std::string& name, const std::string& help);

  // Parses argv (from index `first`). Returns false and prints help if --help was given;
  // throws ConfigError with a clear message on unknown options or missing values.
  bool parse(int argc, char** argv, int first = 1);

  std::string get(const std::string& name) const;
  double get_double(const std::string& name) const;
  int get_int(const std::string& name) const;
  bool has(const std::string& name) const;  // option given on the command line (or has a default)
  bool flag_set(const std::string& name) const;
  std::vector<std::string> get_multi(const std::string& name) const;
  const std::vector<std::string>& positionals() const { return positional_values_; }

  std::string help() const;

 private:
  struct Spec {
    std::string help;
    std::optional<std::string> default_value;
    bool is_flag = false, is_multi = false, required = false;
  };
  std::string program_, summary_;
  std::vector<std::string> order_;
  std::map<std::string, Spec> specs_;
  std::vector<std::pair<std::string, std::string>> positional_specs_;
  std::map<std::string, std::vector<std::string>> values_;
  std::vector<std::string> positional_values_;
};

// The body of every program's main(): runs `run`, prints a one-line error on failure and returns
// the exit code (configuration/usage errors 2, anything else 1). Every message starts with
// `program` ("cslam-x: ..."; a ConfigError that already names it is printed as it is).
int run_main(const char* program, int argc, char** argv, int (*run)(int, char**));

}  // namespace cslam
