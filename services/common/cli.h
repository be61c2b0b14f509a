// Command-line parsing shared by every godhand program: declare the options once, get --help
// (generated from the declarations, defaults shown), strict number parsing, and the project's
// convention for bad arguments: one line "PROGRAM: reason" plus "try PROGRAM --help" on stderr
// and exit status 2.
//
//   godhand::Cli cli("godhand-solver", "Solves one hand cluster ...");
//   std::string lab;  int rate = 90;  bool quiet = false;
//   cli.option("lab", &lab, "FILE", "lab configuration (deploy/lab/local.pbtxt)");
//   cli.option("rate", &rate, "HZ", "solver rate in live mode");
//   cli.flag("quiet", &quiet, "no progress lines");
//   cli.parse(argc, argv);
//   if (lab.empty()) cli.fail("--lab FILE is required");
//
// Syntax: `--name value` or `--name=value`; flags take no value. The value of `--name value` may
// not itself start with "--" (write `--name=--odd` for that); negative numbers are fine. A
// single-valued option given twice keeps the last value (so appended arguments override
// earlier ones); `multi` options collect every occurrence in order. Positional arguments are
// rejected. Names are declared without the leading "--" (a leading "--" is accepted and
// stripped). Declaring a name twice, or "help"/"h", is a programming error (std::logic_error).
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace godhand {

class Cli {
 public:
  /// `program` names the executable in usage and errors; `synopsis` is the paragraph --help
  /// prints under the usage line (printed as given: wrap it yourself with '\n').
  Cli(std::string program, std::string synopsis);

  /// --NAME sets *value to true.
  void flag(const std::string& name, bool* value, const std::string& help);
  /// --NAME META: a string.
  void option(const std::string& name, std::string* value, const std::string& meta, const std::string& help);
  /// --NAME META: a whole decimal integer within int's range.
  void option(const std::string& name, int* value, const std::string& meta, const std::string& help);
  /// --NAME META: a finite number (the whole string must parse; no NaN, no infinity, no overflow).
  void option(const std::string& name, double* value, const std::string& meta, const std::string& help);
  /// --NAME META, repeatable: every value appended to *values in order.
  void multi(const std::string& name, std::vector<std::string>* values, const std::string& meta, const std::string& help);

  /// Parses argv[1..argc-1] into the declared variables. --help / -h prints the usage to stdout
  /// and exits 0; any error calls fail() (exit 2). Variables keep their values when not given.
  void parse(int argc, char** argv);

  /// "PROGRAM: reason" (newlines in reason become spaces) and "try PROGRAM --help" on stderr,
  /// then exit(2). For checks the main does after parse().
  [[noreturn]] void fail(const std::string& reason) const;

  /// Text printed by --help after the options (exit statuses, examples); "" = none.
  void epilog(const std::string& text) { epilog_ = text; }

  /// The text --help prints.
  std::string usage() const;

  const std::string& program() const { return program_; }

 private:
  struct Opt {
    std::string name;   ///< without "--"
    std::string meta;   ///< "" for flags
    std::string help;
    std::string def;    ///< default shown by --help ("" = none)
    bool takes_value = true;
    std::function<std::string(const std::string& value)> set;  ///< "" or the error (one line)
  };
  Opt& add(const std::string& name, const std::string& meta, const std::string& help);
  const Opt* find(const std::string& name) const;

  std::string program_, synopsis_, epilog_;
  std::vector<Opt> opts_;
};

}  // namespace godhand
