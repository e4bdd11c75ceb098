// End to end through the Modbus backend: the real `revolve scan` with the synthetic camera and a
// turntable that is a Modbus drive: `revolve simulate-drive` or the independent pymodbus peer,
// over TCP on 127.0.0.1 and RTU over a socat pty pair. The backend publishes the read-back angle
// to the simulated plate, so the synthetic camera renders the object where the drive says it
// is; an object that is not round (a box) makes a wrong angle show up in the model's accuracy.
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../turntable/test_support.h"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using revolve::turntable::test_support::ChildProcess;
using revolve::turntable::test_support::HaveProgram;
using revolve::turntable::test_support::kPython;
using revolve::turntable::test_support::kSocat;
using revolve::turntable::test_support::PtyPair;
using revolve::turntable::test_support::ReadAll;
using revolve::turntable::test_support::TempDir;
using revolve::turntable::test_support::WaitFor;
using revolve::turntable::test_support::WaitForPort;
using ::testing::HasSubstr;

const std::string kRevolve = REVOLVE_BIN;
const std::string kPeerScript =
    std::string(REVOLVE_SOURCE_DIR) + "/tests/turntable/peers/generic_drive_peer.py";

// 36 stops of 10 deg, a small fast scan of a box (not round: the angle matters).
std::string ScanConfig(const std::string& modbus_table) {
  return R"([scan]
stops = 36
step_deg = 10.0
settle_ms = 0
move_timeout_s = 5.0

[turntable]
backend = "modbus"
[turntable.modbus]
)" + modbus_table +
         R"(
speed_deg_per_s = 3600
acceleration_deg_per_s2 = 36000
poll_ms = 2
response_timeout_ms = 200
connect_timeout_ms = 1000
stall_timeout_ms = 500

[camera]
backend = "synthetic"
[camera.synthetic]
width_px = 320
height_px = 240
object = "box"
radius_mm = 30.0
height_mm = 60.0
target_height_mm = 30.0
distance_mm = 450.0
noise_sigma = 0.0

[reconstruct]
resolution = 48
volume_radius_mm = 55.0
volume_height_mm = 80.0
formats = ["ply"]
)";
}

struct RunResult {
  int exit_code = -1;
  std::string out;
};

class TurntableScanE2e : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!HaveProgram(kRevolve.c_str())) GTEST_SKIP() << "revolve binary missing";
  }

  RunResult Run(const std::string& args) {
    const fs::path out = dir_.path() / "revolve.out";
    const std::string cmd =
        fmt::format("timeout 60 {} {} >{} 2>&1 </dev/null", kRevolve, args, out.string());
    const int status = std::system(cmd.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadAll(out)};
  }

  // Runs the scan and checks the scan folder: complete, 36 stops, each read back within
  // tolerance of exactly k * 10 deg, and a model close to the true box.
  void ScanAndCheck(const std::string& modbus_table) {
    const fs::path config = dir_.path() / "rig.toml";
    std::ofstream(config) << ScanConfig(modbus_table);
    const fs::path scan = dir_.path() / "scan";
    const RunResult r = Run("scan --config " + config.string() + " --out " + scan.string());
    ASSERT_EQ(r.exit_code, 0) << r.out << (peer_ ? peer_->Logs() : "");
    EXPECT_THAT(r.out, HasSubstr("36/36"));
    const auto manifest = nlohmann::json::parse(ReadAll(scan / "manifest.json"));
    EXPECT_EQ(manifest["state"], "complete");
    EXPECT_THAT(manifest["turntable"].get<std::string>(), HasSubstr("modbus"));
    ASSERT_EQ(manifest["stops"].size(), 36u);
    for (const auto& stop : manifest["stops"]) {
      const int k = stop["index"].get<int>();
      EXPECT_DOUBLE_EQ(stop["commanded_deg"].get<double>(), k * 10.0);
      // 0.05 deg tolerance + half a count (3200 counts per turn).
      EXPECT_NEAR(stop["readback_deg"].get<double>(), k * 10.0, 0.06) << k;
    }
    const auto report = nlohmann::json::parse(ReadAll(scan / "report.json"));
    if (report.contains("accuracy") && report["accuracy"].contains("mean_surface_distance_mm")) {
      // A camera that saw the wrong angles would carve a round blob several mm off the box.
      EXPECT_LT(report["accuracy"]["mean_surface_distance_mm"].get<double>(), 2.5)
          << report.dump(2);
    }
  }

  int StartSimulatorTcp(const std::vector<std::string>& extra = {}) {
    const fs::path port_file = dir_.path() / "sim.port";
    std::vector<std::string> argv = {kRevolve, "simulate-drive", "--profile",   "generic",
                                     "--tcp",  "127.0.0.1:0",    "--port-file", port_file.string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    peer_ = std::make_unique<ChildProcess>(argv, dir_.path() / "sim");
    const std::optional<int> port = WaitForPort(port_file, 5000ms);
    EXPECT_TRUE(port) << peer_->Logs();
    return port.value_or(1);
  }

  static std::string Tcp(int port) {
    return fmt::format(
        "transport = \"tcp\"\nhost = \"127.0.0.1\"\nport = {}\nprofile = \"generic\"", port);
  }
  static std::string Rtu(const fs::path& device) {
    return fmt::format(
        "transport = \"rtu\"\nport = \"{}\"\nbaud = 115200\nslave_id = 1\nprofile = \"generic\"",
        device.string());
  }

  bool HavePymodbus() {
    return HaveProgram(kPython) &&
           std::system(
               "/usr/bin/python3 -c 'import pymodbus.server, serial_asyncio' "
               "2>/dev/null") == 0;
  }

  TempDir dir_;
  std::unique_ptr<PtyPair> pty_;
  std::unique_ptr<ChildProcess> peer_;
};

TEST_F(TurntableScanE2e, ModbusTcpSimulator) { ScanAndCheck(Tcp(StartSimulatorTcp())); }

TEST_F(TurntableScanE2e, ModbusRtuSimulator) {
  if (!HaveProgram(kSocat)) GTEST_SKIP() << "socat is missing";
  pty_ = std::make_unique<PtyPair>(dir_.path());
  ASSERT_TRUE(pty_->ready()) << pty_->Logs();
  peer_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{kRevolve, "simulate-drive", "--profile", "generic", "--rtu",
                               pty_->a().string(), "--baud", "115200"},
      dir_.path() / "sim");
  ASSERT_TRUE(
      WaitFor([&] { return peer_->Output().find("listening") != std::string::npos; }, 5000ms))
      << peer_->Logs();
  ScanAndCheck(Rtu(pty_->b()));
}

TEST_F(TurntableScanE2e, ModbusTcpPymodbusPeer) {
  if (!HavePymodbus()) GTEST_SKIP() << "python3-pymodbus / python3-serial-asyncio missing";
  const fs::path port_file = dir_.path() / "py.port";
  peer_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{kPython, kPeerScript, "--tcp", "127.0.0.1:0", "--port-file",
                               port_file.string()},
      dir_.path() / "py");
  const std::optional<int> port = WaitForPort(port_file, 10000ms);
  ASSERT_TRUE(port) << peer_->Logs();
  ScanAndCheck(Tcp(*port));
}

TEST_F(TurntableScanE2e, ModbusRtuPymodbusPeer) {
  if (!HaveProgram(kSocat)) GTEST_SKIP() << "socat is missing";
  if (!HavePymodbus()) GTEST_SKIP() << "python3-pymodbus / python3-serial-asyncio missing";
  pty_ = std::make_unique<PtyPair>(dir_.path());
  ASSERT_TRUE(pty_->ready()) << pty_->Logs();
  peer_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{kPython, kPeerScript, "--rtu", pty_->a().string(), "--baud",
                               "115200"},
      dir_.path() / "py");
  ASSERT_TRUE(
      WaitFor([&] { return peer_->Output().find("generic drive") != std::string::npos; }, 10000ms))
      << peer_->Logs();
  ScanAndCheck(Rtu(pty_->b()));
}

// A drive alarm in the middle of a scan: the scan fails with the drive's words, the motor is
// stopped and powered down, and the folder says how far it got.
TEST_F(TurntableScanE2e, DriveAlarmMidScanStopsAndExplains) {
  const int port = StartSimulatorTcp({"--fault", "alarm@5:0.5", "--alarm-code", "48"});
  const fs::path config = dir_.path() / "rig.toml";
  std::ofstream(config) << ScanConfig(Tcp(port));
  const fs::path scan = dir_.path() / "scan";
  const RunResult r = Run("scan --config " + config.string() + " --out " + scan.string());
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_THAT(r.out, HasSubstr("overcurrent: check the motor wiring"));
  const auto manifest = nlohmann::json::parse(ReadAll(scan / "manifest.json"));
  EXPECT_EQ(manifest["state"], "failed");
  EXPECT_EQ(manifest["error"]["code"], "alarm");
  EXPECT_THAT(manifest["error"]["message"].get<std::string>(), HasSubstr("alarm 0x30"));
  EXPECT_EQ(manifest["stops"].size(), 5u);
  // The drive is stopped and de-energized (disable_at_end), with the alarm still latched.
  const fs::path check = dir_.path() / "check.toml";
  std::ofstream(check) << "[turntable]\nbackend = \"modbus\"\ndisable_at_end = false\n"
                       << "[turntable.modbus]\n"
                       << Tcp(port) << "\n";
  const RunResult status = Run("turntable --config " + check.string() + " status");
  EXPECT_EQ(status.exit_code, 0) << status.out;
  EXPECT_THAT(status.out, HasSubstr("stopped"));
  EXPECT_THAT(status.out, HasSubstr("disabled"));
  EXPECT_THAT(status.out, HasSubstr("ALARM 0x30"));
}

}  // namespace
