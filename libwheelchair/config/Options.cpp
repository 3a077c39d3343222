#include "libwheelchair/config/Options.h"
#include "libwheelchair/util/Text.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

namespace wheelchair::config {

namespace {

using util::trim;

std::string fmtNumber(double v) {
  return fmt::format("{}", v);
}  // shortest exact text

double checkedNumber(const std::string& s, const std::string& where, const Range& r) {
  const double x = parseStrictNumber(s, where);
  if (!r.contains(x))
    throw std::runtime_error(fmt::format("{}: {} is out of range {}", where, s, r.text()));
  return x;
}

double integral(const std::string& s, const std::string& where, const Range& r, double lo,
                double hi) {
  const double x = checkedNumber(s, where, r);
  if (x != std::floor(x) || x < lo || x > hi)
    throw std::runtime_error(fmt::format("{}: '{}' is not an integer", where, s));
  return x;
}

// Levenshtein distance, for "did you mean".
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> d(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) d[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = d[0];
    d[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = d[j];
      d[j] = std::min({d[j] + 1, d[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return d[b.size()];
}

std::string didYouMean(const std::string& name, const std::set<std::string>& known) {
  std::string best;
  std::size_t best_d = std::max<std::size_t>(2, name.size() / 3) + 1;
  for (const auto& k : known) {
    const std::size_t d = editDistance(name, k);
    if (d < best_d) best_d = d, best = k;
  }
  return best.empty() ? "" : fmt::format(" (did you mean {}?)", best);
}

struct Registry {
  std::vector<OptionsFactory> factories;
  bool lenient = false, complete = false;
};
Registry& registry() {
  static Registry r;
  return r;
}

void problem(const std::string& message) {
  if (!registry().lenient) throw std::runtime_error(message);
  std::cerr << "warning: " << message << " (ignored: --lenient)\n";
}

}  // namespace

// --- Range ---------------------------------------------------------------------------------
bool Range::contains(double x) const {
  return (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi);
}

std::string Range::text() const {
  const bool has_lo = std::isfinite(lo), has_hi = std::isfinite(hi);
  if (has_lo && has_hi)
    return fmt::format("{}{}, {}{}", lo_open ? "(" : "[", fmtNumber(lo), fmtNumber(hi),
                       hi_open ? ")" : "]");
  if (has_lo) return fmt::format("{} {}", lo_open ? ">" : ">=", fmtNumber(lo));
  if (has_hi) return fmt::format("{} {}", hi_open ? "<" : "<=", fmtNumber(hi));
  return "any";
}

// --- IniFile -------------------------------------------------------------------------------
IniFile::IniFile(const std::string& text, std::string origin)
    : mrpt::config::CConfigFileMemory(text), origin_(std::move(origin)) {
  std::istringstream in(text);
  std::string line, section;
  for (int n = 1; std::getline(in, line); ++n) {
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#' || t[0] == ';') continue;
    if (t.front() == '[') {
      const auto close = t.find(']');
      section = trim(t.substr(1, close == std::string::npos ? std::string::npos : close - 1));
      entries_.push_back({section, "", n});
      continue;
    }
    const auto eq = t.find('=');
    entries_.push_back({section, trim(t.substr(0, eq)), n});
  }
}

int IniFile::lineOf(const std::string& section, const std::string& key) const {
  for (const auto& e : entries_)
    if (e.section == section && e.key == key) return e.line;
  return 0;
}

void IniFile::copyIndex(const IniFile& other) {
  origin_ = other.origin_;
  entries_ = other.entries_;
}

std::string keyLocation(const mrpt::config::CConfigFileBase& ini, const std::string& section,
                        const std::string& key) {
  const std::string sk =
      key.empty() ? fmt::format("[{}]", section) : fmt::format("[{}] {}", section, key);
  const auto* f = dynamic_cast<const IniFile*>(&ini);
  if (!f) return sk;
  const int line = f->lineOf(section, key);
  return line > 0 ? fmt::format("{}:{}: {}", f->origin(), line, sk)
                  : fmt::format("{}: {}", f->origin(), sk);
}

double parseStrictNumber(const std::string& text, const std::string& where) {
  const std::string t = trim(text);
  const char* b = t.data();
  const char* e = t.data() + t.size();
  if (b != e && *b == '+') ++b;
  double x = 0;
  const auto [ptr, ec] = std::from_chars(b, e, x);
  if (b == e || ec != std::errc() || ptr != e || !std::isfinite(x))
    throw std::runtime_error(fmt::format("{}: '{}' is not a number", where, text));
  return x;
}

// --- Options -------------------------------------------------------------------------------
Options::Options(std::string section, std::string help)
    : section_(std::move(section)), help_(std::move(help)) {}

Options& Options::add(const char* key, std::string help,
                      std::function<void(const std::string&, const std::string&)> read,
                      std::function<std::string()> write) {
  keys_.push_back({key, std::move(help), std::move(read), std::move(write)});
  return *this;
}

namespace {
std::string withRange(const char* help, const Range& r) {
  const std::string t = r.text();
  return t == "any" ? std::string(help) : fmt::format("{}; {}", help, t);
}
}  // namespace

Options& Options::real(const char* key, double& v, const char* help, Range r) {
  return add(
      key, withRange(help, r),
      [&v, r](const std::string& s, const std::string& w) { v = checkedNumber(s, w, r); },
      [&v] { return fmtNumber(v); });
}

Options& Options::integer(const char* key, int& v, const char* help, Range r) {
  return add(
      key, withRange(help, r),
      [&v, r](const std::string& s, const std::string& w) {
        v = static_cast<int>(
            integral(s, w, r, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
      },
      [&v] { return std::to_string(v); });
}

Options& Options::integer(const char* key, int64_t& v, const char* help, Range r) {
  return add(
      key, withRange(help, r),
      [&v, r](const std::string& s, const std::string& w) {
        v = static_cast<int64_t>(integral(s, w, r, -9.007199254740992e15, 9.007199254740992e15));
      },
      [&v] { return std::to_string(v); });
}

Options& Options::flag(const char* key, bool& v, const char* help) {
  return add(
      key, std::string(help) + " (0/1)",
      [&v](const std::string& s, const std::string& w) {
        if (s == "1" || s == "true" || s == "yes" || s == "on")
          v = true;
        else if (s == "0" || s == "false" || s == "no" || s == "off")
          v = false;
        else
          throw std::runtime_error(fmt::format("{}: expected 0 or 1, got '{}'", w, s));
      },
      [&v] { return std::string(v ? "1" : "0"); });
}

Options& Options::text(const char* key, std::string& v, const char* help) {
  return add(
      key, help, [&v](const std::string& s, const std::string&) { v = s; }, [&v] { return v; });
}

Options& Options::oneOf(const char* key, std::string& v, std::vector<std::string> allowed,
                        const char* help) {
  std::string all;
  for (const auto& a : allowed) all += (all.empty() ? "" : " | ") + a;
  return add(
      key, fmt::format("{} ({})", help, all),
      [&v, allowed, all](const std::string& s, const std::string& w) {
        if (std::find(allowed.begin(), allowed.end(), s) == allowed.end())
          throw std::runtime_error(fmt::format("{}: expected {}, got '{}'", w, all, s));
        v = s;
      },
      [&v] { return v; });
}

Options& Options::custom(const char* key, std::function<void(const std::string&)> read,
                         std::function<std::string()> write, const char* help) {
  return add(
      key, help,
      [read](const std::string& s, const std::string& w) {
        try {
          read(s);
        } catch (const std::exception& e) {
          throw std::runtime_error(fmt::format("{}: {}", w, e.what()));
        }
      },
      std::move(write));
}

Options& Options::numberedKeys(const char* prefix, const char* help) {
  numbered_prefixes_.push_back(prefix);
  help_ += fmt::format("{}{}N: {}", help_.empty() ? "" : "\n", prefix, help);
  return *this;
}

Options& Options::anyKey(const char* help) {
  any_key_ = true;
  help_ += fmt::format("{}{}", help_.empty() ? "" : "\n", help);
  return *this;
}

void Options::load(const mrpt::config::CConfigFileBase& ini) const {
  for (const Key& k : keys_) {
    std::string t = trim(ini.read_string(section_, k.name, "", false));
    if (t.size() >= 2 && t.front() == '"' && t.back() == '"') t = trim(t.substr(1, t.size() - 2));
    if (t.empty()) continue;  // missing key: keep the current value
    k.read(t, keyLocation(ini, section_, k.name));
  }
}

void Options::checkUnknownKeys(const IniFile& ini) const {
  const auto names = keyNames();
  const std::set<std::string> known(names.begin(), names.end());
  for (const auto& e : ini.entries())
    if (e.section == section_ && !e.key.empty() && !knows(e.key))
      problem(fmt::format("{}:{}: [{}] {}: unknown key{}", ini.origin(), e.line, e.section, e.key,
                          didYouMean(e.key, known)));
}

void Options::save(mrpt::config::CConfigFileBase& ini) const {
  for (const Key& k : keys_) ini.write(section_, k.name, k.write());
}

std::string Options::dump() const {
  std::string s = fmt::format("[{}]\n", section_);
  if (!help_.empty()) {
    std::istringstream in(help_);
    for (std::string l; std::getline(in, l);) s += "# " + l + "\n";
  }
  for (const Key& k : keys_) s += fmt::format("# {}\n{} = {}\n", k.help, k.name, k.write());
  return s;
}

bool Options::knows(const std::string& key) const {
  if (any_key_) return true;
  for (const Key& k : keys_)
    if (k.name == key) return true;
  for (const auto& p : numbered_prefixes_)
    if (key.size() > p.size() && key.compare(0, p.size(), p) == 0 &&
        std::all_of(key.begin() + p.size(), key.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return true;
  return false;
}

std::vector<std::string> Options::keyNames() const {
  std::vector<std::string> n;
  for (const Key& k : keys_) n.push_back(k.name);
  return n;
}

// --- registry ------------------------------------------------------------------------------
bool registerOptions(OptionsFactory factory) {
  registry().factories.push_back(std::move(factory));
  return true;
}

std::vector<Options> registeredOptions() {
  std::vector<Options> all;
  for (const auto& f : registry().factories)
    for (auto& t : f()) all.push_back(std::move(t));
  // By section name: the registration order is the static initialisers' order, which the
  // linker decides (it changed with link-time optimisation), and `config --dump` must not.
  std::stable_sort(all.begin(), all.end(),
                   [](const Options& a, const Options& b) { return a.section() < b.section(); });
  return all;
}

void setLenient(bool l) {
  registry().lenient = l;
}
bool lenient() {
  return registry().lenient;
}
void setAllSectionsRegistered(bool complete) {
  registry().complete = complete;
}

void checkIni(const IniFile& ini) {
  const auto tables = registeredOptions();
  for (const auto& t : tables) t.load(ini);  // values: strict numbers, ranges, choices
  std::map<std::string, std::vector<const Options*>> by_section;
  for (const auto& t : tables) by_section[t.section()].push_back(&t);
  std::set<std::string> sections;
  for (const auto& [s, v] : by_section) sections.insert(s);
  std::map<std::pair<std::string, std::string>, int> first_line;
  for (const auto& e : ini.entries()) {
    const auto [at, fresh] = first_line.emplace(std::make_pair(e.section, e.key), e.line);
    if (!fresh && !e.key.empty())
      problem(fmt::format("{}:{}: [{}] {}: duplicate key (first at line {})", ini.origin(), e.line,
                          e.section, e.key, at->second));
    const auto it = by_section.find(e.section);
    if (it == by_section.end()) {
      if (!registry().complete) continue;  // a module this program does not link
      if (e.key.empty() || e.section.empty())
        problem(fmt::format("{}:{}: [{}]{}: unknown section{}", ini.origin(), e.line, e.section,
                            e.key.empty() ? "" : " " + e.key, didYouMean(e.section, sections)));
      continue;
    }
    if (e.key.empty()) continue;
    bool known = false;
    std::set<std::string> names;
    for (const Options* t : it->second) {
      known |= t->knows(e.key);
      for (const auto& n : t->keyNames()) names.insert(n);
    }
    if (!known)
      problem(fmt::format("{}:{}: [{}] {}: unknown key{}", ini.origin(), e.line, e.section, e.key,
                          didYouMean(e.key, names)));
  }
}

}  // namespace wheelchair::config
