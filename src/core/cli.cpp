#include "core/cli.h"

#include <iostream>
#include <sstream>

#include "core/error.h"

namespace cslam {

CliArgs::CliArgs(std::string program, std::string summary)
    : program_(std::move(program)), summary_(std::move(summary)) {}

CliArgs& CliArgs::option(const std::string& name, const std::string& help, std::optional<std::string> def) {
  Spec s;
  s.help = help;
  s.default_value = def;
  s.required = !def.has_value();
  specs_[name] = s;
  order_.push_back(name);
  return *this;
}

CliArgs& CliArgs::multi_option(const std::string& name, const std::string& help) {
  Spec s;
  s.help = help;
  s.is_multi = true;
  specs_[name] = s;
  order_.push_back(name);
  return *this;
}

CliArgs& CliArgs::flag(const std::string& name, const std::string& help) {
  Spec s;
  s.help = help;
  s.is_flag = true;
  specs_[name] = s;
  order_.push_back(name);
  return *this;
}

CliArgs& CliArgs::positional(const std::string& name, const std::string& help) {
  positional_specs_.emplace_back(name, help);
  return *this;
}

bool CliArgs::parse(int argc, char** argv, int first) {
  for (int i = first; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::cout << help();
      return false;
    }
    if (arg.rfind("--", 0) == 0 && arg.size() > 2) {
      std::string name = arg.substr(2), value;
      bool inline_value = false;
      if (auto eq = name.find('='); eq != std::string::npos) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
        inline_value = true;
      }
      auto it = specs_.find(name);
      if (it == specs_.end()) throw ConfigError(program_ + ": unknown option --" + name + " (see --help)");
      const Spec& s = it->second;
      if (s.is_flag) {
        if (inline_value) throw ConfigError(program_ + ": --" + name + " takes no value");
        values_[name] = {"1"};
      } else if (s.is_multi) {
        auto& v = values_[name];
        if (inline_value) v.push_back(value);
        while (i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0) v.push_back(argv[++i]);
        if (v.empty()) throw ConfigError(program_ + ": --" + name + " needs at least one value");
      } else {
        if (!inline_value) {
          if (i + 1 >= argc) throw ConfigError(program_ + ": --" + name + " needs a value");
          value = argv[++i];
        }
        values_[name] = {value};
      }
    } else {
      positional_values_.push_back(arg);
    }
  }
  for (const auto& [name, s] : specs_)
    if (s.required && !s.is_flag && !s.is_multi && !values_.count(name))
      throw ConfigError(program_ + ": missing required option --" + name + " (see --help)");
  if (positional_values_.size() < positional_specs_.size())
    throw ConfigError(program_ + ": missing argument " + positional_specs_[positional_values_.size()].first +
                      " (see --help)");
  if (positional_values_.size() > positional_specs_.size())
    throw ConfigError(program_ + ": unexpected argument '" + positional_values_[positional_specs_.size()] +
                      "' (see --help)");
  return true;
}

std::string CliArgs::get(const std::string& name) const {
  if (auto it = values_.find(name); it != values_.end()) return it->second.front();
  auto s = specs_.find(name);
  if (s == specs_.end()) throw std::logic_error("CliArgs: undeclared option " + name);
  if (!s->second.default_value) throw ConfigError(program_ + ": --" + name + " not given");
  return *s->second.default_value;
}

double CliArgs::get_double(const std::string& name) const {
  const std::string v = get(name);
  size_t used = 0;
  double d = 0;
  try {
    d = std::stod(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != v.size()) throw ConfigError(program_ + ": --" + name + " expects a number, got '" + v + "'");
  return d;
}

int CliArgs::get_int(const std::string& name) const {
  const std::string v = get(name);
  size_t used = 0;
  int d = 0;
  try {
    d = std::stoi(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != v.size()) throw ConfigError(program_ + ": --" + name + " expects a whole number, got '" + v + "'");
  return d;
}

bool CliArgs::has(const std::string& name) const {
  if (values_.count(name)) return true;
  auto s = specs_.find(name);
  return s != specs_.end() && s->second.default_value.has_value() && !s->second.default_value->empty();
}

bool CliArgs::flag_set(const std::string& name) const { return values_.count(name) > 0; }

std::vector<std::string> CliArgs::get_multi(const std::string& name) const {
  if (auto it = values_.find(name); it != values_.end()) return it->second;
  return {};
}

std::string CliArgs::help() const {
  std::ostringstream os;
  os << "Usage: " << program_;
  for (const auto& [name, h] : positional_specs_) os << " " << name;
  os << " [options]\n" << summary_ << "\n";
  if (!positional_specs_.empty()) {
    os << "\nArguments:\n";
    for (const auto& [name, h] : positional_specs_) os << "  " << name << "\n      " << h << "\n";
  }
  os << "\nOptions:\n";
  for (const auto& name : order_) {
    const Spec& s = specs_.at(name);
    os << "  --" << name << (s.is_flag ? "" : (s.is_multi ? " V..." : " V"));
    if (s.required)
      os << "   (required)";
    else if (s.default_value && !s.default_value->empty())
      os << "   (default: " << *s.default_value << ")";
    os << "\n      " << s.help << "\n";
  }
  os << "  --help\n      Show this help.\n";
  return os.str();
}

int run_main(const char* program, int argc, char** argv, int (*run)(int, char**)) {
  try {
    return run(argc, argv);
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    std::cerr << (what.rfind(program, 0) == 0 ? "" : std::string(program) + ": ") << what << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return 1;
  }
}

}  // namespace cslam
