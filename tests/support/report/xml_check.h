#pragma once
// A minimal XML well-formedness check for the SVG files we write (no XML library on the machine):
// one root element, every start tag closed in order, attributes quoted, entities known, no stray
// '<' or '&'. Returns an empty string if well-formed, else what is wrong and where.
#include <cctype>
#include <string>
#include <vector>

namespace cslam::test {

inline std::string xml_wellformed_error(const std::string& doc) {
  std::vector<std::string> stack;
  std::size_t i = 0, roots = 0;
  auto at = [&](std::size_t p) { return " at offset " + std::to_string(p); };
  auto check_text = [&](std::size_t begin, std::size_t end) -> std::string {
    for (std::size_t p = begin; p < end; ++p) {
      if (doc[p] == '>') return "stray '>'" + at(p);
      if (doc[p] != '&') continue;
      const std::size_t semi = doc.find(';', p);
      if (semi == std::string::npos || semi > end) return "unterminated entity" + at(p);
      const std::string e = doc.substr(p + 1, semi - p - 1);
      if (e != "amp" && e != "lt" && e != "gt" && e != "quot" && e != "apos" && (e.empty() || e[0] != '#'))
        return "unknown entity &" + e + ";" + at(p);
    }
    return "";
  };
  while (i < doc.size()) {
    const std::size_t lt = doc.find('<', i);
    const std::size_t text_end = lt == std::string::npos ? doc.size() : lt;
    if (auto e = check_text(i, text_end); !e.empty()) return e;
    if (stack.empty() && roots > 0) {
      for (std::size_t p = i; p < text_end; ++p)
        if (!std::isspace(static_cast<unsigned char>(doc[p]))) return "text after the root element" + at(p);
    }
    if (lt == std::string::npos) break;
    if (doc.compare(lt, 5, "<?xml") == 0) {
      const std::size_t end = doc.find("?>", lt);
      if (end == std::string::npos || lt != 0) return "bad XML declaration" + at(lt);
      i = end + 2;
      continue;
    }
    if (doc.compare(lt, 4, "<!--") == 0) {
      const std::size_t end = doc.find("-->", lt);
      if (end == std::string::npos) return "unterminated comment" + at(lt);
      i = end + 3;
      continue;
    }
    const bool closing = lt + 1 < doc.size() && doc[lt + 1] == '/';
    std::size_t p = lt + (closing ? 2 : 1);
    const std::size_t name_begin = p;
    while (p < doc.size() &&
           (std::isalnum(static_cast<unsigned char>(doc[p])) || doc[p] == '-' || doc[p] == ':' || doc[p] == '_'))
      ++p;
    const std::string name = doc.substr(name_begin, p - name_begin);
    if (name.empty()) return "tag without a name" + at(lt);
    if (closing) {
      while (p < doc.size() && std::isspace(static_cast<unsigned char>(doc[p]))) ++p;
      if (p >= doc.size() || doc[p] != '>') return "bad closing tag </" + name + at(lt);
      if (stack.empty() || stack.back() != name) return "closing </" + name + "> does not match" + at(lt);
      stack.pop_back();
      i = p + 1;
      continue;
    }
    // Attributes: name="value" or name='value'.
    bool self_closing = false;
    for (;;) {
      while (p < doc.size() && std::isspace(static_cast<unsigned char>(doc[p]))) ++p;
      if (p >= doc.size()) return "unterminated tag <" + name + at(lt);
      if (doc[p] == '>') break;
      if (doc.compare(p, 2, "/>") == 0) {
        self_closing = true;
        ++p;
        break;
      }
      const std::size_t attr_begin = p;
      while (p < doc.size() && doc[p] != '=' && !std::isspace(static_cast<unsigned char>(doc[p])) && doc[p] != '>') ++p;
      if (p == attr_begin || p >= doc.size() || doc[p] != '=')
        return "attribute without value in <" + name + at(attr_begin);
      ++p;
      if (p >= doc.size() || (doc[p] != '"' && doc[p] != '\'')) return "unquoted attribute in <" + name + at(p);
      const char q = doc[p];
      const std::size_t close = doc.find(q, p + 1);
      if (close == std::string::npos) return "unterminated attribute in <" + name + at(p);
      if (doc.find('<', p + 1) < close) return "'<' inside an attribute of <" + name + at(p);
      if (auto e = check_text(p + 1, close); !e.empty() && e.rfind("stray", 0) != 0) return e;
      p = close + 1;
    }
    if (stack.empty()) {
      if (++roots > 1) return "second root element <" + name + at(lt);
    }
    if (!self_closing) stack.push_back(name);
    i = p + 1;
  }
  if (!stack.empty()) return "unclosed <" + stack.back() + ">";
  if (roots != 1) return "no root element";
  return "";
}

}  // namespace cslam::test
