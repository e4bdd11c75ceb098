// The Modbus backend against real peers over real links: libmodbus on our side; on the other,
// `revolve simulate-drive` (revolve's own framing) or an independent pymodbus server, over TCP on
// 127.0.0.1 and RTU over a fresh socat pty pair per test. Every peer is started by the test and
// killed in teardown; every wait is bounded.
#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "test_support.h"
#include "turntable/modbus/frame.h"
#include "turntable/modbus/libmodbus_transport.h"
#include "turntable/modbus/profile.h"
#include "turntable/turntable.h"

namespace revolve::turntable {
namespace {

using namespace std::chrono_literals;
using test_support::ChildProcess;
using test_support::HaveProgram;
using test_support::kPython;
using test_support::kSocat;
using test_support::PtyPair;
using test_support::TempDir;
using test_support::WaitFor;
using test_support::WaitForPort;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

const std::string kRevolve = REVOLVE_BIN;
const std::string kPeerScript =
    std::string(REVOLVE_SOURCE_DIR) + "/tests/turntable/peers/generic_drive_peer.py";

Clock::time_point In(Clock::duration d) { return Clock::now() + d; }

// Fast motion and short timeouts, so a stop takes a few ms and a fault a few 100 ms.
constexpr char kFast[] = R"(
speed_deg_per_s = 3600
acceleration_deg_per_s2 = 36000
poll_ms = 2
response_timeout_ms = 100
byte_timeout_ms = 20
connect_timeout_ms = 500
stall_timeout_ms = 300
)";

Expected<TurntableOptions> OptionsFrom(const std::string& modbus_table) {
  // The Document must outlive the parse only; the options are plain values.
  const std::string text =
      "[turntable]\nbackend = \"modbus\"\n[turntable.modbus]\n" + modbus_table + kFast;
  Expected<config::Document> document = config::Parse(text, "peer_test.toml");
  if (!document) return std::unexpected(document.error());
  Expected<config::Section> section = config::Section::Root(*document).Child("turntable");
  if (!section) return std::unexpected(section.error());
  return ParseOptions(*section);
}

std::unique_ptr<Turntable> Open(const std::string& modbus_table,
                                std::shared_ptr<SimulatedPlate> plate = nullptr) {
  Expected<TurntableOptions> options = OptionsFrom(modbus_table);
  EXPECT_TRUE(options) << options.error().ToString();
  if (!options) return nullptr;
  Expected<std::unique_ptr<Turntable>> table = Create(*options, std::move(plate));
  EXPECT_TRUE(table) << table.error().ToString();
  return table ? std::move(*table) : nullptr;
}

std::string TcpTable(int port, const std::string& profile = "generic") {
  return fmt::format("transport = \"tcp\"\nhost = \"127.0.0.1\"\nport = {}\nprofile = \"{}\"\n",
                     port, profile);
}

std::string RtuTable(const fs::path& device, const std::string& profile = "generic",
                     int baud = 115200, const std::string& parity = "none") {
  return fmt::format(
      "transport = \"rtu\"\nport = \"{}\"\nbaud = {}\nparity = \"{}\"\nslave_id = 1\n"
      "profile = \"{}\"\n",
      device.string(), baud, parity, profile);
}

void HomeAndScan(Turntable& table, int stops, SimulatedPlate* plate) {
  Expected<void> homed = table.Home(In(5s));
  ASSERT_TRUE(homed) << homed.error().ToString();
  for (int k = 0; k < stops; ++k) {
    const double target = k * 360.0 / stops;
    Expected<void> moved = table.MoveTo(target, In(3s));
    ASSERT_TRUE(moved) << k << ": " << moved.error().ToString();
    Expected<TurntableState> state = table.State();
    ASSERT_TRUE(state) << state.error().ToString();
    EXPECT_NEAR(state->angle_deg, target, 0.06) << k;  // 0.05 tolerance + half a count
    EXPECT_TRUE(state->in_position) << k;
    EXPECT_FALSE(state->moving) << k;
    if (plate != nullptr) {
      EXPECT_NEAR(plate->angle_deg.load(), target, 0.06) << k;
    }
  }
}

class PeerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!HaveProgram(kRevolve.c_str())) GTEST_SKIP() << "revolve binary missing: " << kRevolve;
  }

  // `revolve simulate-drive` on TCP, port chosen by the kernel.
  int StartSimulatorTcp(std::vector<std::string> extra = {},
                        const std::string& profile = "generic") {
    const fs::path port_file = dir_.path() / "sim.port";
    std::vector<std::string> argv = {
        kRevolve,      "simulate-drive", "--profile",        profile,         "--tcp",
        "127.0.0.1:0", "--port-file",    port_file.string(), "--watchdog-ms", "300"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    peer_ = std::make_unique<ChildProcess>(argv, dir_.path() / "sim");
    std::optional<int> port = WaitForPort(port_file, 5000ms);
    EXPECT_TRUE(port) << peer_->Logs();
    return port.value_or(1);
  }

  // A fresh pty pair with `revolve simulate-drive` on end a; the client uses end b.
  bool StartSimulatorRtu(std::vector<std::string> extra = {},
                         const std::string& profile = "generic", int baud = 115200) {
    if (!HaveProgram(kSocat)) return false;
    pty_ = std::make_unique<PtyPair>(dir_.path());
    EXPECT_TRUE(pty_->ready()) << pty_->Logs();
    std::vector<std::string> argv = {
        kRevolve,           "simulate-drive", "--profile",          profile,         "--rtu",
        pty_->a().string(), "--baud",         std::to_string(baud), "--watchdog-ms", "300"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    peer_ = std::make_unique<ChildProcess>(argv, dir_.path() / "sim");
    const bool ready =
        WaitFor([&] { return peer_->Output().find("listening") != std::string::npos; }, 5000ms);
    EXPECT_TRUE(ready) << peer_->Logs();
    return ready;
  }

  TempDir dir_;
  std::unique_ptr<PtyPair> pty_;
  std::unique_ptr<ChildProcess> peer_;
};

// --- 36 stops against the simulator ---

TEST_F(PeerTest, SimulatorOverTcpThirtySixStops) {
  const int port = StartSimulatorTcp();
  auto plate = std::make_shared<SimulatedPlate>();
  std::unique_ptr<Turntable> table = Open(TcpTable(port), plate);
  ASSERT_TRUE(table);
  EXPECT_THAT(table->Describe(), HasSubstr("tcp 127.0.0.1:"));
  HomeAndScan(*table, 36, plate.get());
}

TEST_F(PeerTest, SimulatorOverRtuThirtySixStops) {
  if (!StartSimulatorRtu()) GTEST_SKIP() << "socat is missing";
  auto plate = std::make_shared<SimulatedPlate>();
  std::unique_ptr<Turntable> table = Open(RtuTable(pty_->b()), plate);
  ASSERT_TRUE(table);
  HomeAndScan(*table, 36, plate.get());
}

TEST_F(PeerTest, EveryVendorProfileOverRtu) {
  if (!HaveProgram(kSocat)) GTEST_SKIP() << "socat is missing";
  struct Case {
    std::string profile;
    int baud;
    std::string parity;
  };
  for (const Case& c : {Case{"mks_servo42d", 38400, "none"}, Case{"leadshine_pr", 115200, "none"},
                        Case{"oriental_az", 115200, "even"}}) {
    SCOPED_TRACE(c.profile);
    ASSERT_TRUE(StartSimulatorRtu({"--accel-hz-s", "1000000"}, c.profile, c.baud));
    // This test is about each vendor's registers, not about timeouts: a drive simulator just
    // started on a loaded machine may take longer than kFast's 100 ms to its first reply.
    Expected<TurntableOptions> options =
        OptionsFrom(RtuTable(pty_->b(), c.profile, c.baud, c.parity));
    ASSERT_TRUE(options) << options.error().ToString();
    options->modbus.response_timeout_ms = 1000;
    Expected<std::unique_ptr<Turntable>> created = Create(*options, nullptr);
    ASSERT_TRUE(created) << created.error().ToString();
    std::unique_ptr<Turntable> table = std::move(*created);
    HomeAndScan(*table, 4, nullptr);
    table.reset();
    peer_.reset();
    pty_.reset();
  }
}

// --- 36 stops against the independent pymodbus peer ---

class PymodbusTest : public PeerTest {
 protected:
  void SetUp() override {
    PeerTest::SetUp();
    if (IsSkipped()) return;
    if (!HaveProgram(kPython)) GTEST_SKIP() << "/usr/bin/python3 is missing";
    if (std::system("/usr/bin/python3 -c 'import pymodbus.server, serial_asyncio' 2>/dev/null") !=
        0) {
      GTEST_SKIP() << "python3-pymodbus or python3-serial-asyncio is missing";
    }
  }
};

TEST_F(PymodbusTest, PymodbusOverTcpThirtySixStops) {
  const fs::path port_file = dir_.path() / "py.port";
  peer_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{kPython, kPeerScript, "--tcp", "127.0.0.1:0", "--port-file",
                               port_file.string()},
      dir_.path() / "py");
  std::optional<int> port = WaitForPort(port_file, 10000ms);
  ASSERT_TRUE(port) << peer_->Logs();
  auto plate = std::make_shared<SimulatedPlate>();
  std::unique_ptr<Turntable> table = Open(TcpTable(*port), plate);
  ASSERT_TRUE(table);
  HomeAndScan(*table, 36, plate.get());
}

TEST_F(PymodbusTest, PymodbusOverRtuThirtySixStops) {
  if (!HaveProgram(kSocat)) GTEST_SKIP() << "socat is missing";
  pty_ = std::make_unique<PtyPair>(dir_.path());
  ASSERT_TRUE(pty_->ready()) << pty_->Logs();
  peer_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{kPython, kPeerScript, "--rtu", pty_->a().string(), "--baud",
                               "115200"},
      dir_.path() / "py");
  ASSERT_TRUE(
      WaitFor([&] { return peer_->Output().find("generic drive") != std::string::npos; }, 10000ms))
      << peer_->Logs();
  auto plate = std::make_shared<SimulatedPlate>();
  std::unique_ptr<Turntable> table = Open(RtuTable(pty_->b()), plate);
  ASSERT_TRUE(table);
  HomeAndScan(*table, 36, plate.get());
}

// --- faults over real links ---

// Runs one move that the peer breaks; returns its error and checks it came before the deadline.
Error FailingMove(Turntable& table, double target, Clock::duration budget) {
  const auto start = Clock::now();
  Expected<void> moved = table.MoveTo(target, In(5s));
  EXPECT_LT(Clock::now() - start, budget);
  EXPECT_FALSE(moved);
  return moved ? Error{} : moved.error();
}

TEST_F(PeerTest, NoReplyOverRtuIsLinkDown) {
  if (!StartSimulatorRtu({"--fault", "no-reply@1"})) GTEST_SKIP() << "socat is missing";
  std::unique_ptr<Turntable> table = Open(RtuTable(pty_->b()));
  ASSERT_TRUE(table);
  ASSERT_TRUE(table->MoveTo(10.0, In(3s)));
  // 3 tries of the move's trigger and 3 of "stop", 100 ms each.
  const Error error = FailingMove(*table, 20.0, 1500ms);
  EXPECT_EQ(error.code, ErrorCode::kLinkDown) << error.message;
  EXPECT_THAT(error.message, HasSubstr("no reply within 100 ms"));
  EXPECT_THAT(error.message, HasSubstr("after 3 attempts"));
}

TEST_F(PeerTest, CorruptedCrcOverRtuIsProtocol) {
  if (!StartSimulatorRtu({"--fault", "corrupt@1"})) GTEST_SKIP() << "socat is missing";
  std::unique_ptr<Turntable> table = Open(RtuTable(pty_->b()));
  ASSERT_TRUE(table);
  ASSERT_TRUE(table->MoveTo(10.0, In(3s)));
  const Error error = FailingMove(*table, 20.0, 1500ms);
  EXPECT_EQ(error.code, ErrorCode::kProtocol) << error.message;
  EXPECT_THAT(error.message, HasSubstr("bad CRC"));
}

TEST_F(PeerTest, ExceptionResponseOverTcpIsProtocolAndTheMotorStays) {
  const int port = StartSimulatorTcp({"--fault", "exception@1:3"});
  std::unique_ptr<Turntable> table = Open(TcpTable(port));
  ASSERT_TRUE(table);
  ASSERT_TRUE(table->MoveTo(10.0, In(3s)));
  const Error error = FailingMove(*table, 20.0, 1000ms);
  EXPECT_EQ(error.code, ErrorCode::kProtocol) << error.message;
  EXPECT_THAT(error.message, HasSubstr("exception 0x03 (illegal data value)"));
  Expected<TurntableState> state = table->State();
  ASSERT_TRUE(state) << state.error().ToString();
  EXPECT_FALSE(state->moving);
  EXPECT_NEAR(state->angle_deg, 10.0, 0.06);
}

TEST_F(PeerTest, AlarmDuringMoveOverTcpIsAlarmWithTheDrivesCode) {
  const int port = StartSimulatorTcp({"--fault", "alarm@1:0.5", "--alarm-code", "49"});
  std::unique_ptr<Turntable> table = Open(TcpTable(port));
  ASSERT_TRUE(table);
  ASSERT_TRUE(table->Home(In(3s)));
  ASSERT_TRUE(table->MoveTo(10.0, In(3s)));
  const Error error = FailingMove(*table, 100.0, 1000ms);
  EXPECT_EQ(error.code, ErrorCode::kAlarm) << error.message;
  EXPECT_THAT(error.message, HasSubstr("alarm 0x31: position error too large"));
  Expected<TurntableState> state = table->State();
  ASSERT_TRUE(state);
  EXPECT_FALSE(state->moving);
  EXPECT_EQ(state->alarm_code, 0x31);
  EXPECT_NEAR(state->angle_deg, 55.0, 1.0);  // stopped halfway
  ASSERT_TRUE(table->Home(In(3s)));          // resets the alarm
  EXPECT_TRUE(table->MoveTo(10.0, In(3s)));
}

TEST_F(PeerTest, StallOverRtuIsStalledAndTheMotorStopped) {
  if (!StartSimulatorRtu({"--fault", "stall@1:0.3"})) GTEST_SKIP() << "socat is missing";
  std::unique_ptr<Turntable> table = Open(RtuTable(pty_->b()));
  ASSERT_TRUE(table);
  ASSERT_TRUE(table->MoveTo(10.0, In(3s)));
  const Error error = FailingMove(*table, 100.0, 1500ms);
  EXPECT_EQ(error.code, ErrorCode::kStalled) << error.message;
  Expected<TurntableState> state = table->State();
  ASSERT_TRUE(state);
  EXPECT_FALSE(state->moving);
}

TEST_F(PeerTest, LinkDroppedMidMoveOverTcpIsLinkDown) {
  const int port = StartSimulatorTcp({"--fault", "link-drop@1:0.2"});
  std::unique_ptr<Turntable> table = Open(TcpTable(port));
  ASSERT_TRUE(table);
  ASSERT_TRUE(table->MoveTo(10.0, In(3s)));
  const Error error = FailingMove(*table, 300.0, 2000ms);
  EXPECT_EQ(error.code, ErrorCode::kLinkDown) << error.message;
  EXPECT_TRUE(peer_->Running());  // the drive lives on; only the link is gone
  EXPECT_THAT(peer_->Errors() + peer_->Output(), HasSubstr("link drop"));
}

TEST_F(PeerTest, ATransientNoReplyIsRetried) {
  if (!StartSimulatorRtu({"--fault", "no-reply@1:1"})) GTEST_SKIP() << "socat is missing";
  std::unique_ptr<Turntable> table = Open(RtuTable(pty_->b()));
  ASSERT_TRUE(table);
  ASSERT_TRUE(table->MoveTo(10.0, In(3s)));
  Expected<void> moved = table->MoveTo(20.0, In(3s));
  ASSERT_TRUE(moved) << moved.error().ToString();
}

// --- the link itself ---

TEST_F(PeerTest, SerialPortIsLockedAgainstASecondOpen) {
  if (!StartSimulatorRtu()) GTEST_SKIP() << "socat is missing";
  Expected<TurntableOptions> options = OptionsFrom(RtuTable(pty_->b()));
  ASSERT_TRUE(options);
  auto first = modbus::LibmodbusTransport::Open(options->modbus);
  ASSERT_TRUE(first) << first.error().ToString();
  auto second = modbus::LibmodbusTransport::Open(options->modbus);
  ASSERT_FALSE(second);
  EXPECT_EQ(second.error().code, ErrorCode::kBusy);
  EXPECT_THAT(second.error().message, HasSubstr("locked by another process"));
  first->reset();
  auto third = modbus::LibmodbusTransport::Open(options->modbus);  // released on close
  EXPECT_TRUE(third) << third.error().ToString();
}

TEST_F(PeerTest, StaleInputIsFlushedAfterConnecting) {
  if (!HaveProgram(kSocat)) GTEST_SKIP() << "socat is missing";
  pty_ = std::make_unique<PtyPair>(dir_.path());
  ASSERT_TRUE(pty_->ready());
  {
    // Bytes sent toward the client's end before it opens (a drive's late reply, noise).
    const int fd = ::open(pty_->a().c_str(), O_RDWR | O_NOCTTY);
    ASSERT_GE(fd, 0);
    const std::vector<std::uint8_t> junk = modbus::FromHex("01 04 02 12 34 AA BB 55 55");
    ASSERT_EQ(::write(fd, junk.data(), junk.size()), static_cast<ssize_t>(junk.size()));
    std::this_thread::sleep_for(50ms);
    ::close(fd);
  }
  peer_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{kRevolve, "simulate-drive", "--profile", "generic", "--rtu",
                               pty_->a().string(), "--baud", "115200"},
      dir_.path() / "sim");
  ASSERT_TRUE(
      WaitFor([&] { return peer_->Output().find("listening") != std::string::npos; }, 5000ms));
  std::unique_ptr<Turntable> table = Open(RtuTable(pty_->b()) + "retries = 0\n");
  ASSERT_TRUE(table);
  Expected<TurntableState> state = table->State();  // the first transaction must work
  EXPECT_TRUE(state) << state.error().ToString();
}

TEST_F(PeerTest, Rs485ModeOnAnAdapterWithoutItIsUnsupported) {
  if (!HaveProgram(kSocat)) GTEST_SKIP() << "socat is missing";
  pty_ = std::make_unique<PtyPair>(dir_.path());
  ASSERT_TRUE(pty_->ready());
  Expected<TurntableOptions> options = OptionsFrom(RtuTable(pty_->b()) + "rs485 = true\n");
  ASSERT_TRUE(options);
  Expected<std::unique_ptr<Turntable>> table = Create(*options, nullptr);
  ASSERT_FALSE(table);
  EXPECT_EQ(table.error().code, ErrorCode::kUnsupported);
  EXPECT_THAT(table.error().message, HasSubstr("rs485 = false"));
}

TEST_F(PeerTest, OpenErrorsAreTyped) {
  Expected<TurntableOptions> missing = OptionsFrom(RtuTable(dir_.path() / "no_such_tty"));
  ASSERT_TRUE(missing);
  Expected<std::unique_ptr<Turntable>> table = Create(*missing, nullptr);
  ASSERT_FALSE(table);
  EXPECT_EQ(table.error().code, ErrorCode::kNotFound);
  // A TCP port nobody listens on: refused at once.
  const int port = StartSimulatorTcp();
  peer_.reset();
  Expected<TurntableOptions> refused = OptionsFrom(TcpTable(port));
  ASSERT_TRUE(refused);
  const auto start = Clock::now();
  table = Create(*refused, nullptr);
  ASSERT_FALSE(table);
  EXPECT_EQ(table.error().code, ErrorCode::kLinkDown);
  EXPECT_LT(Clock::now() - start, 1s);
}

// What libmodbus puts on the wire is byte-for-byte the golden frame (pymodbus's encoding).
TEST_F(PeerTest, LibmodbusWritesTheGoldenBytes) {
  if (!HaveProgram(kSocat)) GTEST_SKIP() << "socat is missing";
  pty_ = std::make_unique<PtyPair>(dir_.path());
  ASSERT_TRUE(pty_->ready());
  const int fd = ::open(pty_->a().c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
  ASSERT_GE(fd, 0);
  Expected<TurntableOptions> options =
      OptionsFrom(RtuTable(pty_->b(), "mks_servo42d", 38400) + "retries = 0\n");
  ASSERT_TRUE(options);
  options->modbus.response_timeout_ms = 20;
  auto transport = modbus::LibmodbusTransport::Open(options->modbus);
  ASSERT_TRUE(transport) << transport.error().ToString();
  Expected<modbus::DriveProfile> profile = modbus::LoadProfileFile(options->modbus.profile_path);
  ASSERT_TRUE(profile);
  auto wire = [&](const modbus::Request& request) {
    (void)(*transport)->Execute(request);  // nobody answers: times out after 20 ms
    std::vector<std::uint8_t> bytes(256);
    const ssize_t n = ::read(fd, bytes.data(), bytes.size());
    bytes.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
    return modbus::ToHex(bytes);
  };
  modbus::Variables variables(profile->params.begin(), profile->params.end());
  variables["target"] = 12345;
  variables["speed_rpm"] = 60;
  auto steps = modbus::RenderCommand(*profile, *profile->FindCommand("move"), variables);
  ASSERT_TRUE(steps);
  EXPECT_EQ(wire(*(*steps)[0].request), "01 10 00 FE 00 04 08 00 F0 00 3C 00 00 30 39 68 B4");
  steps = modbus::RenderCommand(*profile, *profile->FindCommand("enable"), variables);
  EXPECT_EQ(wire(*(*steps)[0].request), "01 06 00 F3 00 01 B8 39");
  EXPECT_EQ(wire(modbus::Request{modbus::FunctionCode::kReadInputRegisters, 0x00F1, 1, {}}),
            "01 04 00 F1 00 01 60 39");
  ::close(fd);
}

// --- the CLI for bring-up ---

TEST_F(PeerTest, TurntableCommandMovesAndReports) {
  const int port = StartSimulatorTcp();
  const fs::path config = dir_.path() / "rig.toml";
  std::ofstream(config) << "[turntable]\nbackend = \"modbus\"\n[turntable.modbus]\n"
                        << TcpTable(port) << kFast;
  auto run = [&](const std::string& args) {
    const fs::path out = dir_.path() / "cli.out";
    const std::string cmd = "timeout 30 " + kRevolve + " turntable --config " + config.string() +
                            " " + args + " >" + out.string() + " 2>&1 </dev/null";
    const int status = std::system(cmd.c_str());
    return std::pair(WIFEXITED(status) ? WEXITSTATUS(status) : -1, test_support::ReadAll(out));
  };
  auto [code, text] = run("move 45");  // 400 counts exactly
  EXPECT_EQ(code, 0) << text;
  EXPECT_THAT(text, HasSubstr("angle 45.000 deg (read back), stopped, in position"));
  std::tie(code, text) = run("status");
  EXPECT_EQ(code, 0) << text;
  EXPECT_THAT(text, HasSubstr("angle 45.000 deg (read back), stopped, in position"));
  EXPECT_THAT(text, HasSubstr("disabled"));  // disable_at_end: the last run powered it down
  std::tie(code, text) = run("home");
  EXPECT_EQ(code, 0) << text;
  EXPECT_THAT(text, HasSubstr("angle 0.000 deg"));
  EXPECT_THAT(text, HasSubstr("homed"));
  std::tie(code, text) = run("profiles");
  EXPECT_EQ(code, 0) << text;
  EXPECT_THAT(text, HasSubstr("oriental_az"));
}

}  // namespace
}  // namespace revolve::turntable
