#include "support/report/text_output.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "core/error.h"

namespace cslam::report {

namespace {

std::string markdown_cell(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '|')
      out += "\\|";
    else if (c == '\n' || c == '\r')
      out += ' ';
    else
      out += c;
  }
  return out;
}

std::string cell(const std::vector<std::string>& row, std::size_t i) { return i < row.size() ? row[i] : std::string(); }

}  // namespace

std::string to_markdown(const Table& table) {
  const std::size_t n = table.header.size();
  std::string out = "|";
  for (const auto& h : table.header) out += " " + markdown_cell(h) + " |";
  out += "\n|";
  for (std::size_t i = 0; i < n; ++i) {
    const char a = i < table.align.size() ? table.align[i] : 'l';
    out += a == 'r' ? "---:|" : a == 'c' ? ":---:|" : "---|";
  }
  out += "\n";
  for (const auto& row : table.rows) {
    out += "|";
    for (std::size_t i = 0; i < n; ++i) out += " " + markdown_cell(cell(row, i)) + " |";
    out += "\n";
  }
  return out;
}

std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (char c : text) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string to_csv(const Table& table) {
  std::string out;
  auto line = [&out](const std::vector<std::string>& fields, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      if (i) out += ',';
      out += csv_field(cell(fields, i));
    }
    out += "\n";
  };
  line(table.header, table.header.size());
  for (const auto& row : table.rows) line(row, table.header.size());
  return out;
}

std::string format_number(double value, int decimals) {
  if (!std::isfinite(value)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  return buf;
}

Spread spread(const std::vector<double>& values) {
  std::vector<double> v;
  for (double x : values)
    if (std::isfinite(x)) v.push_back(x);
  Spread s;
  s.n = int(v.size());
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.min = v.front();
  s.max = v.back();
  s.median = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  return s;
}

std::string format_spread(const Spread& s, int decimals) {
  if (s.n == 0) return "n/a";
  const std::string median = format_number(s.median, decimals);
  const std::string lo = format_number(s.min, decimals), hi = format_number(s.max, decimals);
  if (s.n == 1 || lo == hi) return median;
  return median + " (" + lo + "–" + hi + ")";
}

void write_text_atomic(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(path, "cannot write");
    out << text;
    out.flush();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw InputError(path, "write failed");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw InputError(path, "cannot rename the temporary file into place");
  }
}

}  // namespace cslam::report
