#pragma once
// Reading whitespace-separated text files with '#' comments, reporting file:line on error.
#include <functional>
#include <string>
#include <vector>

namespace cslam {

// Calls fn(line_number, tokens) for every non-empty, non-comment line. Throws InputError if the
// file cannot be opened; fn may throw InputError itself.
void for_each_text_row(const std::string& path,
                       const std::function<void(int line, const std::vector<std::string>& tokens)>& fn);

// Strict number parsing: the whole token must be a finite number, else InputError(path, line).
double parse_double(const std::string& token, const std::string& path, int line, const char* what);

}  // namespace cslam
