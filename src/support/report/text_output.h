#pragma once
// Text outputs of experiment reports: Markdown and CSV tables, number formatting with "n/a" for
// missing values, median (min–max) cells, atomic file writes.
#include <string>
#include <vector>

namespace cslam::report {

struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  // each row as long as the header (shorter rows are padded)
  std::vector<char> align;                     // per column 'l', 'r' or 'c' (default 'l')
};

// GitHub-flavoured Markdown; '|' in cells is escaped, newlines become spaces.
std::string to_markdown(const Table& table);

// RFC 4180 CSV: a field is quoted if it holds a comma, quote, CR or LF; quotes are doubled.
std::string csv_field(const std::string& text);
std::string to_csv(const Table& table);

// Fixed decimals; NaN or infinite -> "n/a".
std::string format_number(double value, int decimals);

// Median and range of repeated measurements (NaN values are ignored).
struct Spread {
  int n = 0;  // finite values
  double median = 0, min = 0, max = 0;
};
Spread spread(const std::vector<double>& values);
// "0.0206 (0.0198–0.0241)"; a single value or identical values print alone; no values -> "n/a".
std::string format_spread(const Spread& s, int decimals);

// Writes text to path through a temporary file and a rename. Throws InputError naming the path.
void write_text_atomic(const std::string& path, const std::string& text);

}  // namespace cslam::report
