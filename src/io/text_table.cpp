#include "io/text_table.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace cslam {

void for_each_text_row(const std::string& path, const std::function<void(int, const std::vector<std::string>&)>& fn) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open file");
  std::string line;
  int number = 0;
  std::vector<std::string> tokens;
  while (std::getline(in, line)) {
    ++number;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ss(line);
    tokens.clear();
    for (std::string tok; ss >> tok;) tokens.push_back(tok);
    if (tokens.empty()) continue;
    fn(number, tokens);
  }
}

double parse_double(const std::string& token, const std::string& path, int line, const char* what) {
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(token, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != token.size()) throw InputError(path, line, std::string("malformed ") + what + " '" + token + "'");
  if (!std::isfinite(value)) throw InputError(path, line, std::string(what) + " is not finite ('" + token + "')");
  return value;
}

}  // namespace cslam
