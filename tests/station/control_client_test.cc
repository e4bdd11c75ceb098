#include <gtest/gtest.h>

#include "station/commands/control_client.h"

namespace revolve::station {
namespace {

TEST(ControlClientTest, ProgressBarAndEta) {
  EXPECT_EQ(ProgressBar(0.0, 10), "[----------]");
  EXPECT_EQ(ProgressBar(0.5, 10), "[#####-----]");
  EXPECT_EQ(ProgressBar(1.0, 10), "[##########]");
  EXPECT_EQ(ProgressBar(2.0, 4), "[####]");
  EXPECT_EQ(ProgressBar(-1.0, 4), "[----]");
  EXPECT_EQ(FormatEta(-1), "--");
  EXPECT_EQ(FormatEta(42.4), "42 s");
  EXPECT_EQ(FormatEta(65), "1:05");
  EXPECT_EQ(FormatEta(3725), "1:02:05");
}

TEST(ControlClientTest, ProgressLineShowsStateStopBarAndEta) {
  const nlohmann::json e = {{"state", "capturing"},
                            {"stop", 11},
                            {"stops", 36},
                            {"stops_done", 11},
                            {"progress", 0.275},
                            {"eta_s", 42.0},
                            {"scan_id", "20261121-230105"}};
  const std::string line = FormatProgressLine(e);
  EXPECT_NE(line.find("capturing"), std::string::npos) << line;
  EXPECT_NE(line.find("stop 12/36"), std::string::npos) << line;
  EXPECT_NE(line.find("[#######"), std::string::npos) << line;
  EXPECT_NE(line.find("28%"), std::string::npos) << line;
  EXPECT_NE(line.find("ETA 42 s"), std::string::npos) << line;
  EXPECT_NE(line.find("20261121-230105"), std::string::npos) << line;

  const nlohmann::json failed = {{"state", "failed"},
                                 {"stop", -1},
                                 {"stops", 36},
                                 {"stops_done", 3},
                                 {"progress", 0.075},
                                 {"note", "alarm"},
                                 {"alarm", {{"code", 49}, {"text", "x"}}}};
  const std::string f = FormatProgressLine(failed);
  EXPECT_EQ(f.find("ETA"), std::string::npos) << f;
  EXPECT_NE(f.find("3/36 stops"), std::string::npos) << f;
  EXPECT_NE(f.find("drive alarm 49"), std::string::npos) << f;
  // Missing fields never throw.
  EXPECT_NO_THROW((void)FormatProgressLine(nlohmann::json::object()));
  EXPECT_NO_THROW((void)FormatStatus(nlohmann::json::object()));
}

TEST(ControlClientTest, StatusAndList) {
  const nlohmann::json s = {{"state", "failed"},
                            {"scan", {{"id", "a"}, {"recipe", "quick"}, {"dir", "/s/a"}}},
                            {"stops", 12},
                            {"stops_done", 3},
                            {"progress", 0.2},
                            {"error", {{"code", "no_device"}, {"message", "camera gone"}}},
                            {"devices", {{"ok", true}, {"description", "mock / synthetic"}}},
                            {"led", "fault"}};
  const std::string text = FormatStatus(s);
  EXPECT_NE(text.find("failed"), std::string::npos);
  EXPECT_NE(text.find("no_device: camera gone"), std::string::npos) << text;
  EXPECT_NE(text.find("led       fault"), std::string::npos) << text;
  const nlohmann::json scans = nlohmann::json::array({{{"id", "a"},
                                                       {"state", "complete"},
                                                       {"recipe", "default"},
                                                       {"stops_done", 36},
                                                       {"stops_planned", 36},
                                                       {"model", {"model/model.ply"}}},
                                                      {{"id", "b"},
                                                       {"state", "interrupted"},
                                                       {"recipe", "default"},
                                                       {"stops_done", 4},
                                                       {"stops_planned", 36}}});
  const std::string list = FormatScanList(scans);
  EXPECT_NE(list.find("model/model.ply"), std::string::npos) << list;
  EXPECT_NE(list.find("interrupted"), std::string::npos) << list;
}

TEST(ControlClientTest, ConnectingToNothingSaysWhatToCheck) {
  auto c = ControlClient::Connect("/nonexistent/revolve.sock");
  ASSERT_FALSE(c.has_value());
  EXPECT_EQ(c.error().code, ErrorCode::kLinkDown);
  EXPECT_NE(c.error().message.find("/nonexistent/revolve.sock"), std::string::npos);
  EXPECT_NE(c.error().message.find("revolved running"), std::string::npos);
}

}  // namespace
}  // namespace revolve::station
