// The architecture page (and the identification page, which names its conditioning step)
// name no function or type that does not exist: every `name(` and every qualified
// `ns::name` they mention is an identifier of the library or the program (comments not
// counted), so a rename or a deletion that leaves the docs behind fails here.
#include "../common/TestUtil.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <regex>
#include <set>
#include <string>

namespace fs = std::filesystem;
using namespace wheelchair;

namespace {

// Every identifier of the C++ sources under libwheelchair/ and apps/, comments removed.
std::set<std::string> sourceIdentifiers() {
  std::set<std::string> ids;
  const std::regex comment(R"(//[^\n]*)"), ident(R"([A-Za-z_][A-Za-z0-9_]*)");
  for (const char* dir : {"libwheelchair", "apps"})
    for (const auto& e : fs::recursive_directory_iterator(test::sourcePath(dir))) {
      const auto ext = e.path().extension();
      if (!e.is_regular_file() || (ext != ".h" && ext != ".cpp")) continue;
      const std::string code = std::regex_replace(test::readFile(e.path().string()), comment, "");
      for (std::sregex_iterator it(code.begin(), code.end(), ident), end; it != end; ++it)
        ids.insert(it->str());
    }
  return ids;
}

// Names a page mentions as code: `f(` and `a::b` inside backticks, `a::b` anywhere (the
// diagrams), with the line they stand on.
std::vector<std::pair<int, std::string>> namedInCode(const std::string& page) {
  std::vector<std::pair<int, std::string>> out;
  const std::regex span("`([^`\n]+)`"), call(R"(([A-Za-z_][A-Za-z0-9_]*)\s*\()"),
      qualified(R"(\b[A-Za-z_]\w*(?:::[A-Za-z_]\w*)+)");
  auto lineAt = [&](std::size_t pos) {
    return 1 + static_cast<int>(std::count(page.begin(), page.begin() + pos, '\n'));
  };
  for (std::sregex_iterator s(page.begin(), page.end(), span), end; s != end; ++s) {
    const std::string code = (*s)[1];
    for (std::sregex_iterator c(code.begin(), code.end(), call); c != end; ++c)
      out.push_back({lineAt(s->position()), (*c)[1]});
  }
  for (std::sregex_iterator q(page.begin(), page.end(), qualified), end; q != end; ++q)
    out.push_back({lineAt(q->position()), q->str()});
  return out;
}

}  // namespace

TEST(Docs, ArchitectureNamesOnlyExistingFunctions) {
  const std::set<std::string> ids = sourceIdentifiers();
  ASSERT_GT(ids.size(), 1000u);
  std::size_t checked = 0;
  for (const char* page : {"docs/architecture.md", "docs/identification.md"}) {
    const std::string text = test::readFile(test::sourcePath(page));
    for (const auto& [line, name] : namedInCode(text)) {
      const std::string last =
          name.substr(name.rfind(':') == std::string::npos ? 0 : name.rfind(':') + 1);
      if (name.rfind("mrpt::", 0) == 0 || name.rfind("std::", 0) == 0) continue;  // external
      ++checked;
      EXPECT_TRUE(ids.count(last))
          << page << ":" << line << ": `" << name << "` is not in libwheelchair/ or apps/";
    }
  }
  EXPECT_GT(checked, 30u);  // the pages do name the code they describe
}
