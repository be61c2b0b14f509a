#include "common/cli.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <stdexcept>

namespace godhand {

namespace {

std::string stripDashes(const std::string& name) { return name.rfind("--", 0) == 0 ? name.substr(2) : name; }

std::string shortest(double x) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

bool startsWithSpace(const std::string& s) { return !s.empty() && std::isspace(static_cast<unsigned char>(s[0])); }

}  // namespace

Cli::Cli(std::string program, std::string synopsis) : program_(std::move(program)), synopsis_(std::move(synopsis)) {}

Cli::Opt& Cli::add(const std::string& name, const std::string& meta, const std::string& help) {
  const std::string n = stripDashes(name);
  if (n.empty() || n[0] == '-' || n.find('=') != std::string::npos || n.find(' ') != std::string::npos)
    throw std::logic_error("Cli: bad option name '" + name + "'");
  if (n == "help" || n == "h") throw std::logic_error("Cli: --help is built in");
  if (find(n)) throw std::logic_error("Cli: option --" + n + " declared twice");
  Opt o;
  o.name = n;
  o.meta = meta.empty() ? "VALUE" : meta;
  o.help = help;
  opts_.push_back(std::move(o));
  return opts_.back();
}

const Cli::Opt* Cli::find(const std::string& name) const {
  for (const Opt& o : opts_)
    if (o.name == name) return &o;
  return nullptr;
}

void Cli::flag(const std::string& name, bool* value, const std::string& help) {
  if (!value) throw std::logic_error("Cli: null variable for --" + name);
  Opt& o = add(name, "", help);
  o.meta.clear();
  o.takes_value = false;
  o.def = *value ? "on" : "";
  o.set = [value](const std::string&) {
    *value = true;
    return std::string();
  };
}

void Cli::option(const std::string& name, std::string* value, const std::string& meta, const std::string& help) {
  if (!value) throw std::logic_error("Cli: null variable for --" + name);
  Opt& o = add(name, meta, help);
  o.def = *value;
  // An empty value is never meant: `--partition "$UNSET"` would silently be "no partition".
  const std::string flag = "--" + o.name;
  o.set = [value, flag](const std::string& v) {
    if (v.empty()) return flag + ": empty value (leave the option out for its default)";
    *value = v;
    return std::string();
  };
}

void Cli::option(const std::string& name, int* value, const std::string& meta, const std::string& help) {
  if (!value) throw std::logic_error("Cli: null variable for --" + name);
  Opt& o = add(name, meta, help);
  o.def = std::to_string(*value);
  const std::string flag = "--" + o.name;
  o.set = [value, flag](const std::string& v) -> std::string {
    char* end = nullptr;
    errno = 0;
    const long x = std::strtol(v.c_str(), &end, 10);
    if (v.empty() || startsWithSpace(v) || *end != '\0') return flag + ": expected an integer, got '" + v + "'";
    if (errno == ERANGE || x < INT_MIN || x > INT_MAX)
      return flag + ": integer out of range [" + std::to_string(INT_MIN) + ", " + std::to_string(INT_MAX) + "], got '" + v + "'";
    *value = static_cast<int>(x);
    return "";
  };
}

void Cli::option(const std::string& name, double* value, const std::string& meta, const std::string& help) {
  if (!value) throw std::logic_error("Cli: null variable for --" + name);
  Opt& o = add(name, meta, help);
  o.def = shortest(*value);
  const std::string flag = "--" + o.name;
  o.set = [value, flag](const std::string& v) -> std::string {
    char* end = nullptr;
    errno = 0;
    const double x = std::strtod(v.c_str(), &end);
    // (strtod also reads hexadecimal, "0x10" = 16: not what a person typing a number means.)
    if (v.empty() || startsWithSpace(v) || *end != '\0' || v.find_first_of("xX") != std::string::npos)
      return flag + ": expected a number, got '" + v + "'";
    if (!std::isfinite(x) || (errno == ERANGE && std::fabs(x) > 1.0)) return flag + ": expected a finite number, got '" + v + "'";
    *value = x;
    return "";
  };
}

void Cli::multi(const std::string& name, std::vector<std::string>* values, const std::string& meta, const std::string& help) {
  if (!values) throw std::logic_error("Cli: null variable for --" + name);
  Opt& o = add(name, meta, help);
  for (const std::string& v : *values) o.def += (o.def.empty() ? "" : " ") + v;
  o.help += (o.help.empty() ? "" : " ") + std::string("(repeatable)");
  const std::string flag = "--" + o.name;
  o.set = [values, flag](const std::string& v) {
    if (v.empty()) return flag + ": empty value";
    values->push_back(v);
    return std::string();
  };
}

std::string Cli::usage() const {
  std::string out = "usage: " + program_ + (opts_.empty() ? "" : " [OPTIONS]") + "\n";
  if (!synopsis_.empty()) {
    out += "\n" + synopsis_;
    if (synopsis_.back() != '\n') out += "\n";
  }
  out += "\nOptions:\n";
  struct Row {
    std::string left, right;
  };
  std::vector<Row> rows;
  for (const Opt& o : opts_) {
    std::string right = o.help;
    if (!o.def.empty()) right += (right.empty() ? "" : " ") + std::string("(default: ") + o.def + ")";
    rows.push_back({"--" + o.name + (o.takes_value ? " " + o.meta : ""), right});
  }
  rows.push_back({"-h, --help", "show this help and exit"});
  size_t width = 0;
  for (const Row& r : rows) width = std::max(width, r.left.size());
  width = std::min<size_t>(width, 26) + 2;
  const std::string indent(2 + width, ' ');
  for (const Row& r : rows) {
    std::string line = "  " + r.left;
    if (r.left.size() + 2 > width) {
      line += "\n" + indent;
    } else {
      line += std::string(width - r.left.size(), ' ');
    }
    for (char c : r.right) {
      line += c;
      if (c == '\n') line += indent;
    }
    out += line + "\n";
  }
  if (!epilog_.empty()) {
    out += "\n" + epilog_;
    if (epilog_.back() != '\n') out += "\n";
  }
  return out;
}

void Cli::fail(const std::string& reason) const {
  std::string r = reason;
  for (char& c : r)
    if (c == '\n' || c == '\r') c = ' ';
  std::cout.flush();
  std::cerr << program_ << ": " << r << "\n"
            << "try " << program_ << " --help\n";
  std::cerr.flush();
  std::exit(2);
}

void Cli::parse(int argc, char** argv) {
  // --help wins wherever it appears (even after a bad argument), as people expect.
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i] ? argv[i] : "";
    if (a == "--") break;
    if (a == "--help" || a == "-h") {
      std::cout << usage();
      std::cout.flush();
      std::exit(0);
    }
  }
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i] ? argv[i] : "";
    if (a.size() < 3 || a.compare(0, 2, "--") != 0) {
      if (a == "--") fail("unexpected argument '--' (this program takes no positional arguments)");
      if (!a.empty() && a[0] == '-' && a.size() > 1) fail("unknown option '" + a + "'");
      fail("unexpected argument '" + a + "' (options start with --)");
    }
    const size_t eq = a.find('=');
    const std::string name = a.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    const Opt* o = find(name);
    if (!o) fail("unknown option '--" + name + "'");
    if (!o->takes_value) {
      if (eq != std::string::npos) fail("--" + name + " takes no value, got '" + a + "'");
      o->set("");
      continue;
    }
    std::string value;
    if (eq != std::string::npos) {
      value = a.substr(eq + 1);
    } else {
      if (i + 1 >= argc) fail("--" + name + ": missing value (--" + name + " " + o->meta + ")");
      value = argv[i + 1] ? argv[i + 1] : "";
      if (value.size() > 2 && value.compare(0, 2, "--") == 0)
        fail("--" + name + ": missing value (--" + name + " " + o->meta + "), got option '" + value + "'");
      ++i;
    }
    const std::string error = o->set(value);
    if (!error.empty()) fail(error);
  }
}

}  // namespace godhand
