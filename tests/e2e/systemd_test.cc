// systemd integration that can be checked without systemd as PID 1: the unit passes
// `systemd-analyze verify` with empty stderr and scores <= 3.0 in `systemd-analyze security`;
// `cmake --install` lays out the binaries, the unit and the example config.
#include <iostream>
#include <regex>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "tests/e2e/daemon_harness.h"

namespace revolve::e2e {
namespace {

class SystemdTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fmt::format("/tmp/rvsd_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    if (RunCommand({"/bin/sh", "-c", "command -v systemd-analyze"}, {}, dir_, 10s).exit_code != 0) {
      GTEST_SKIP() << "systemd-analyze is not installed";
    }
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // The built unit with ExecStart pointing at the built daemon (verify needs it to exist).
  fs::path TestUnit() {
    const std::string unit = ReadAll(fs::path(REVOLVE_BINARY_DIR) / "station/revolved.service");
    EXPECT_FALSE(unit.empty());
    const std::string local = std::regex_replace(unit, std::regex("ExecStart=[^ \n]+"),
                                                 std::string("ExecStart=") + REVOLVED_BIN);
    const fs::path path = dir_ / "revolved.service";
    std::ofstream(path) << local;
    return path;
  }

  fs::path dir_;
};

TEST_F(SystemdTest, UnitPassesVerifyWithEmptyStderr) {
  const fs::path unit = TestUnit();
  const CommandResult r =
      RunCommand({"/usr/bin/systemd-analyze", "verify", "--man=no", unit.string()}, {}, dir_, 60s);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "") << "systemd-analyze verify reported: " << r.err;
  const std::string text = ReadAll(unit);
  for (const char* want :
       {"Type=notify", "WatchdogSec=", "Restart=on-failure", "RestartPreventExitStatus=78",
        "User=revolve", "SupplementaryGroups=video dialout", "StateDirectory=revolved",
        "ConfigurationDirectory=revolved", "RuntimeDirectory=revolve", "ProtectSystem=strict"}) {
    EXPECT_NE(text.find(want), std::string::npos) << want;
  }
}

TEST_F(SystemdTest, SecurityExposureIsAtMostThree) {
  const fs::path unit = TestUnit();
  const CommandResult r = RunCommand(
      {"/usr/bin/systemd-analyze", "security", "--offline=true", "--no-pager", unit.string()}, {},
      dir_, 60s);
  std::smatch m;
  const std::string all = r.out + r.err;
  ASSERT_TRUE(std::regex_search(all, m, std::regex("Overall exposure level for [^:]+: ([0-9.]+)")))
      << all;
  const double exposure = std::stod(m[1]);
  std::cout << "systemd-analyze security: exposure " << exposure << "\n";
  RecordProperty("exposure", m[1].str());
  EXPECT_LE(exposure, 3.0) << all;
}

TEST_F(SystemdTest, InstallLaysOutBinariesUnitAndExampleConfig) {
  const fs::path prefix = dir_ / "prefix";
  const CommandResult r =
      RunCommand({"/usr/bin/cmake", "--install", REVOLVE_BINARY_DIR, "--prefix", prefix.string()},
                 {}, dir_, 120s);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  for (const char* f :
       {"bin/revolve", "bin/revolved", "lib/systemd/system/revolved.service",
        "lib/sysusers.d/revolved.conf", "lib/tmpfiles.d/revolved.conf",
        "share/revolve/examples/revolved.toml", "share/revolve/examples/60-revolve.rules"}) {
    EXPECT_TRUE(fs::exists(prefix / f)) << f;
  }
  // The installed example config is valid.
  const CommandResult check =
      RunCommand({(prefix / "bin/revolve").string(), "check-config",
                  (prefix / "share/revolve/examples/revolved.toml").string()},
                 {}, dir_, 60s);
  EXPECT_EQ(check.exit_code, 0) << check.err;
  // OpenCV's codecs come from the installed plugin, and only when an image needs them
  // (base/image_codecs.h): glibc's loader trace (LD_DEBUG=files) names every library it loads.
  const fs::path plugin = prefix / "lib/revolve/librevolve_imgcodecs.so";
  EXPECT_TRUE(fs::exists(plugin));
  const CommandResult quiet =
      RunCommand({(prefix / "bin/revolve").string(), "check-config",
                  (prefix / "share/revolve/examples/revolved.toml").string()},
                 {"LD_DEBUG=files"}, dir_, 60s);
  EXPECT_EQ(quiet.exit_code, 0);
  EXPECT_EQ(quiet.err.find("imgcodecs"), std::string::npos);
  const CommandResult board = RunCommand({(prefix / "bin/revolve").string(), "calibrate", "board",
                                          "--out", (dir_ / "board.png").string()},
                                         {"LD_DEBUG=files"}, dir_, 60s);
  EXPECT_EQ(board.exit_code, 0) << board.out;
  EXPECT_TRUE(fs::exists(dir_ / "board.png"));
  EXPECT_NE(board.err.find("file=" + plugin.string()), std::string::npos) << board.err;
  // libcamera too, where this build has that backend (capture/libcamera/libcamera_plugin.h): not
  // loaded by a command that opens no camera, loaded from the installed plugin by one that lists
  // them.
  EXPECT_EQ(quiet.err.find("libcamera"), std::string::npos);
  const fs::path camera_plugin = prefix / "lib/revolve/librevolve_libcamera.so";
  if (fs::exists(camera_plugin)) {
    const CommandResult list = RunCommand({(prefix / "bin/revolve").string(), "camera", "list"},
                                          {"LD_DEBUG=files"}, dir_, 60s);
    EXPECT_EQ(list.exit_code, 0) << list.err;
    EXPECT_NE(list.out.find("libcamera: "), std::string::npos) << list.out;
    EXPECT_NE(list.err.find("file=" + camera_plugin.string()), std::string::npos);
  }
  const std::string sysusers = ReadAll(prefix / "lib/sysusers.d/revolved.conf");
  EXPECT_NE(sysusers.find("m revolve video"), std::string::npos);
  EXPECT_NE(sysusers.find("m revolve dialout"), std::string::npos);
}

}  // namespace
}  // namespace revolve::e2e
