#include <random>

#include <gtest/gtest.h>

#include "station/protocol.h"

namespace revolve::station {
namespace {

TEST(ProtocolTest, ParsesEachCommand) {
  nlohmann::json id;
  auto status = ParseRequest(R"({"cmd":"status"})", &id);
  ASSERT_TRUE(status.has_value());
  EXPECT_EQ(status->kind, RequestKind::kStatus);
  EXPECT_TRUE(id.is_null());

  auto start = ParseRequest(R"({"cmd":"start","recipe":"quick","id":7})", &id);
  ASSERT_TRUE(start.has_value()) << start.error().message;
  EXPECT_EQ(start->kind, RequestKind::kStart);
  EXPECT_EQ(start->recipe, "quick");
  EXPECT_EQ(id, 7);

  auto resume = ParseRequest(R"({"cmd":"start","resume":"20261121-230105"})", &id);
  ASSERT_TRUE(resume.has_value());
  EXPECT_EQ(resume->resume, "20261121-230105");

  EXPECT_EQ(ParseRequest(R"({"cmd":"abort"})", &id)->kind, RequestKind::kAbort);
  EXPECT_EQ(ParseRequest(R"({"cmd":"watch"})", &id)->kind, RequestKind::kWatch);
  EXPECT_EQ(ParseRequest(R"({"cmd":"list"})", &id)->kind, RequestKind::kList);
}

TEST(ProtocolTest, MalformedRequestsAreErrorsWithReasons) {
  nlohmann::json id;
  struct Case {
    const char* line;
    ErrorCode code;
  };
  for (const Case& c :
       {Case{"", ErrorCode::kProtocol}, Case{"{", ErrorCode::kProtocol},
        Case{"[1,2]", ErrorCode::kProtocol}, Case{"\"status\"", ErrorCode::kProtocol},
        Case{"{}", ErrorCode::kProtocol}, Case{R"({"cmd":5})", ErrorCode::kProtocol},
        Case{R"({"cmd":"fly"})", ErrorCode::kBadInput},
        Case{R"({"cmd":"start","recipe":3})", ErrorCode::kProtocol},
        Case{R"({"cmd":"start","recipe":""})", ErrorCode::kBadInput},
        Case{R"({"cmd":"status","recipe":"x"})", ErrorCode::kBadInput},
        Case{R"({"cmd":"start","resume":"../etc"})", ErrorCode::kBadInput},
        Case{R"({"cmd":"start","resume":"a/b"})", ErrorCode::kBadInput},
        Case{R"({"cmd":"start","resume":".."})", ErrorCode::kBadInput},
        Case{R"({"cmd":"start","resume":"x","recipe":"y"})", ErrorCode::kBadInput},
        Case{R"({"cmd":"status","id":[1]})", ErrorCode::kProtocol}}) {
    auto r = ParseRequest(c.line, &id);
    ASSERT_FALSE(r.has_value()) << c.line;
    EXPECT_EQ(r.error().code, c.code) << c.line << ": " << r.error().message;
    EXPECT_FALSE(r.error().message.empty());
  }
  // The id of a bad request is still echoed.
  auto r = ParseRequest(R"({"cmd":"fly","id":"a1"})", &id);
  EXPECT_FALSE(r.has_value());
  EXPECT_EQ(id, "a1");
}

TEST(ProtocolTest, RepliesAreSingleJsonLines) {
  const std::string ok = OkLine("x", {{"scan", {{"id", "s1"}}}});
  ASSERT_EQ(ok.back(), '\n');
  EXPECT_EQ(ok.find('\n'), ok.size() - 1);
  const auto j = nlohmann::json::parse(ok);
  EXPECT_EQ(j["ok"], true);
  EXPECT_EQ(j["id"], "x");
  EXPECT_EQ(j["scan"]["id"], "s1");

  const std::string err = ErrorLine(nullptr, Error{ErrorCode::kBusy, "a scan runs\nreally"});
  EXPECT_EQ(err.find('\n'), err.size() - 1);
  const auto e = nlohmann::json::parse(err);
  EXPECT_EQ(e["ok"], false);
  EXPECT_FALSE(e.contains("id"));
  EXPECT_EQ(e["error"]["code"], "busy");

  // Invalid UTF-8 in a message never throws.
  const std::string bad = ErrorLine(nullptr, Error{ErrorCode::kBadInput, "\xff\xfe"});
  EXPECT_NO_THROW(auto parsed = nlohmann::json::parse(bad); (void)parsed);
}

TEST(ProtocolTest, LineSplitterSplitsAndCapsLines) {
  LineSplitter s(10);
  s.Append("abc\nde");
  auto a = s.Next();
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->kind, LineSplitter::Kind::kLine);
  EXPECT_EQ(a->line, "abc");
  EXPECT_FALSE(s.Next().has_value());
  s.Append("f\r\n");
  EXPECT_EQ(s.Next()->line, "def");
  // A line of 11 bytes arriving in pieces: reported once, skipped to its newline.
  s.Append("0123456");
  s.Append("7890");
  auto too_long = s.Next();
  ASSERT_TRUE(too_long.has_value());
  EXPECT_EQ(too_long->kind, LineSplitter::Kind::kTooLong);
  s.Append("still the same line");
  EXPECT_FALSE(s.Next().has_value());
  EXPECT_EQ(s.partial_bytes(), 0u);
  s.Append(" end\nok\n");
  auto ok = s.Next();
  ASSERT_TRUE(ok.has_value());
  EXPECT_EQ(ok->kind, LineSplitter::Kind::kLine);
  EXPECT_EQ(ok->line, "ok");
  // Exactly the limit is fine.
  s.Append("0123456789\n");
  EXPECT_EQ(s.Next()->line, "0123456789");
}

// Random bytes and mutated requests never crash the parser or the splitter, and every answer
// is a well-formed reply line.
TEST(ProtocolTest, FuzzedInputNeverCrashes) {
  std::mt19937 rng(12345);
  const std::vector<std::string> seeds = {
      R"({"cmd":"status"})", R"({"cmd":"start","recipe":"quick","id":1})", R"({"cmd":"watch"})",
      R"({"cmd":"start","resume":"20261121-230105"})", R"({"cmd":"list"})"};
  LineSplitter splitter(256);
  int lines = 0;
  for (int i = 0; i < 20000; ++i) {
    std::string input;
    if (i % 3 == 0) {
      const int n = static_cast<int>(rng() % 300);
      for (int k = 0; k < n; ++k) input += static_cast<char>(rng() % 256);
    } else {
      input = seeds[rng() % seeds.size()];
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int k = 0; k < edits && !input.empty(); ++k) {
        const std::size_t at = rng() % input.size();
        switch (rng() % 3) {
          case 0:
            input[at] = static_cast<char>(rng() % 256);
            break;
          case 1:
            input.erase(at, 1);
            break;
          default:
            input.insert(at, 1, static_cast<char>(rng() % 256));
        }
      }
    }
    input += '\n';
    splitter.Append(input);
    while (auto item = splitter.Next()) {
      ++lines;
      if (item->kind != LineSplitter::Kind::kLine) continue;
      nlohmann::json id;
      auto r = ParseRequest(item->line, &id);
      const std::string reply = r ? OkLine(id, {{"x", 1}}) : ErrorLine(id, r.error());
      ASSERT_EQ(reply.find('\n'), reply.size() - 1);
      ASSERT_NO_THROW(auto parsed = nlohmann::json::parse(reply); (void)parsed);
    }
  }
  EXPECT_GT(lines, 15000);
}

TEST(ProtocolTest, ScanIds) {
  EXPECT_TRUE(IsValidScanId("20261121-230105"));
  EXPECT_TRUE(IsValidScanId("20261121-230105-2"));
  EXPECT_FALSE(IsValidScanId(""));
  EXPECT_FALSE(IsValidScanId("."));
  EXPECT_FALSE(IsValidScanId("a b"));
  EXPECT_FALSE(IsValidScanId("/x"));
  EXPECT_FALSE(IsValidScanId(std::string(200, 'a')));
}

}  // namespace
}  // namespace revolve::station
