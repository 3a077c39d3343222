// One options mechanism for every INI section of the project (MRPT's CLoadableOptions
// contract): each options struct describes its keys ONCE in a key table (config::Options:
// name, bound member, allowed range or choices, one-line help with the unit), and that table
// drives load, save, dump and validation. Every table is registered (registerOptions), so a
// whole file can be checked against the union of all tables when it is loaded:
//
//   - numbers are parsed strictly: the whole value must be one finite number
//     ("2,5", "1.5 m", "nan" are errors, not 2 / 1.5 / NaN as with atof);
//   - a numeric key outside its range is an error ("gate_probability = 5", range [0, 1]);
//   - an unknown key or section is an error naming file, line and key, with the nearest
//     known name ("wheelchair.ini:12: [vehicle] wheel_radus_m: unknown key (did you mean
//     wheel_radius_m?)"); setLenient(true) (`wheelchair --lenient ...`) turns unknown keys
//     and sections, and an empty file, into warnings on stderr.
//
// Missing keys keep the struct's current value (its default); an empty value ("key =")
// counts as missing. Bools read 0/1, true/false, yes/no, on/off.
//
// Example (an options struct):
//   struct MyOptions {
//     double cutoff_hz = 2.0;
//     config::Options options(const std::string& section = "my") {
//       return config::Options(section)
//           .real("cutoff_hz", cutoff_hz, "low-pass cut-off (Hz)", config::Range::above(0));
//     }
//   };
//   // MyOptions.cpp, once: the table joins the registry (file-level key check, dumps).
//   static const bool reg = config::registerOptionsOf<MyOptions>("my");
//   MyOptions o;  o.options().load(cfg.ini());   // throws "file:line: [my] cutoff_hz: ..."
#pragma once

#include <mrpt/config/CConfigFileMemory.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace wheelchair::config {

/// Allowed interval of a numeric key; the default allows any finite number.
struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;

  static Range any() { return {}; }
  static Range atLeast(double lo) { return {lo, std::numeric_limits<double>::infinity()}; }
  static Range above(double lo) {
    return {lo, std::numeric_limits<double>::infinity(), true, false};
  }
  static Range between(double lo, double hi) { return {lo, hi}; }
  bool contains(double x) const;
  std::string text() const;  ///< "[0, 1]", "> 0", ">= 0"
};

/// INI text (MRPT CConfigFile conventions) that also knows the file line of every section
/// and key, so that errors can name them. Lines refer to the text given at construction.
class IniFile : public mrpt::config::CConfigFileMemory {
 public:
  struct Entry {
    std::string section, key;  ///< key empty: the section header line
    int line = 0;              ///< 1-based
  };
  explicit IniFile(const std::string& text = "", std::string origin = "<text>");
  const std::string& origin() const { return origin_; }
  /// Section headers and keys in file order.
  const std::vector<Entry>& entries() const { return entries_; }
  /// Line of `key` in `section` (key empty: the section header); 0 when not in the text.
  int lineOf(const std::string& section, const std::string& key = "") const;
  /// Keeps the origin and line index of `other` (after re-creating the text from it).
  void copyIndex(const IniFile& other);

 private:
  std::string origin_;
  std::vector<Entry> entries_;
};

/// "file:12: [section] key" for an IniFile ("file: [section] key" when the line is unknown);
/// "[section] key" for any other CConfigFileBase.
std::string keyLocation(const mrpt::config::CConfigFileBase& ini, const std::string& section,
                        const std::string& key);

/// Strict number: the whole text (blanks around allowed) is one finite decimal number.
/// Throws std::runtime_error "<where>: '<text>' is not a number".
double parseStrictNumber(const std::string& text, const std::string& where);

/// The key table of one INI section, bound to the members of one options object.
class Options {
 public:
  explicit Options(std::string section, std::string help = "");

  Options& real(const char* key, double& v, const char* help, Range r = {});
  Options& integer(const char* key, int& v, const char* help, Range r = {});
  Options& integer(const char* key, int64_t& v, const char* help, Range r = {});
  Options& flag(const char* key, bool& v, const char* help);
  Options& text(const char* key, std::string& v, const char* help);
  /// A text key restricted to `allowed` values.
  Options& oneOf(const char* key, std::string& v, std::vector<std::string> allowed,
                 const char* help);
  /// An enum key with its value names.
  template <typename E>
  Options& choice(const char* key, E& v, std::vector<std::pair<E, const char*>> names,
                  const char* help);
  /// A key with its own reader (throws std::runtime_error/invalid_argument with a message
  /// that is prefixed by the key's location) and writer.
  Options& custom(const char* key, std::function<void(const std::string&)> read,
                  std::function<std::string()> write, const char* help);
  /// Keys written by the tool whose names are not fixed: `prefix` followed by digits
  /// (e.g. "effect_" for effect_1, effect_2, ...). Read by the struct itself.
  Options& numberedKeys(const char* prefix, const char* help);
  /// Any key is accepted (free-form sections such as [identified] results).
  Options& anyKey(const char* help);

  /// Reads the keys present in the table's section of `ini`: strict numbers, ranges,
  /// choices. Missing keys keep their values. Throws std::runtime_error naming file, line,
  /// section and key. Unknown keys are checked per file by checkIni.
  void load(const mrpt::config::CConfigFileBase& ini) const;
  /// Every key of the table's section in `ini` must be one of the table's (an error naming
  /// file, line and key, with the nearest name; a warning when lenient()).
  void checkUnknownKeys(const IniFile& ini) const;
  /// Writes every fixed key's current value to the table's section.
  void save(mrpt::config::CConfigFileBase& ini) const;
  /// The section as commented INI: "[section]", then per key "# help (range)" and
  /// "key = value".
  std::string dump() const;

  const std::string& section() const { return section_; }
  bool knows(const std::string& key) const;
  std::vector<std::string> keyNames() const;  ///< the fixed keys, in table order

  /// Keeps `owner` (the object the table is bound to) alive as long as the table.
  void keepAlive(std::shared_ptr<void> owner) { owner_ = std::move(owner); }

 private:
  struct Key {
    std::string name, help;
    std::function<void(const std::string& text, const std::string& where)> read;
    std::function<std::string()> write;
  };
  Options& add(const char* key, std::string help,
               std::function<void(const std::string&, const std::string&)> read,
               std::function<std::string()> write);
  std::string section_, help_;
  std::vector<Key> keys_;
  std::vector<std::string> numbered_prefixes_;
  bool any_key_ = false;
  std::shared_ptr<void> owner_;
};

template <typename E>
Options& Options::choice(const char* key, E& v, std::vector<std::pair<E, const char*>> names,
                         const char* help) {
  std::string all;
  for (const auto& kn : names) all += std::string(all.empty() ? "" : " | ") + kn.second;
  auto read = [&v, names, all](const std::string& s, const std::string& where) {
    for (const auto& [k, n] : names)
      if (s == n) {
        v = k;
        return;
      }
    throw std::runtime_error(where + ": expected " + all + ", got '" + s + "'");
  };
  auto write = [&v, names] {
    for (const auto& [k, n] : names)
      if (k == v) return std::string(n);
    return std::string("?");
  };
  return add(key, std::string(help) + " (" + all + ")", read, write);
}

// --- registry -----------------------------------------------------------------------------

/// A factory of key tables bound to default-constructed objects (that the tables own).
using OptionsFactory = std::function<std::vector<Options>()>;
/// Adds tables to the registry; returns true (for a namespace-scope static initialiser).
bool registerOptions(OptionsFactory factory);
/// registerOptions for a struct with `Options options(const std::string& section)`.
template <typename T>
bool registerOptionsOf(const std::string& section) {
  return registerOptions([section] {
    auto o = std::make_shared<T>();
    Options t = o->options(section);
    t.keepAlive(o);
    return std::vector<Options>{t};
  });
}
/// Every registered table (defaults), ordered by section name (stable).
std::vector<Options> registeredOptions();

/// Unknown keys and sections, and an empty file, only warn (stderr) instead of throwing.
void setLenient(bool lenient);
bool lenient();
/// Declares the registry complete (the `wheelchair` program links every module): from then
/// on a section no table knows is an error too. A library user that links only some modules
/// gets unknown keys checked in the sections it knows, and other sections left alone.
void setAllSectionsRegistered(bool complete);

/// Checks `ini` against the registered tables: every value of a known key (strict number,
/// range, choice: always an error), every section and key name, and duplicate keys; throws
/// std::runtime_error "file:line: [section] key: unknown key (did you mean ...?)" for the
/// first problem (unknown names: a warning each on stderr when lenient()).
void checkIni(const IniFile& ini);

}  // namespace wheelchair::config
