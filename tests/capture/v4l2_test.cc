// The V4L2 backend: pixel conversion on known vectors, and the camera against a fake device
// behind the ioctl seam (format negotiation, controls, stale buffers, timeouts, device loss).
#include <linux/videodev2.h>

#include <filesystem>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "capture/v4l2/pixel_convert.h"
#include "capture/v4l2/v4l2_camera.h"
#include "capture/v4l2/v4l2_device.h"
#include "fake_v4l2.h"

namespace revolve::capture {
namespace {

using testing::FakeV4l2;
using namespace std::chrono_literals;

// --- Pixel conversion -------------------------------------------------------------------

TEST(PixelConvert, YuvToBgrKnownVectors) {
  using Bgr = std::array<std::uint8_t, 3>;
  EXPECT_EQ(YuvToBgr(16, 128, 128), (Bgr{0, 0, 0}));         // video black
  EXPECT_EQ(YuvToBgr(235, 128, 128), (Bgr{255, 255, 255}));  // video white
  EXPECT_EQ(YuvToBgr(126, 128, 128), (Bgr{128, 128, 128}));  // mid grey
  // The 75%/100% colour-bar codes of BT.601 (rounded to 8 bits): within 2 levels.
  auto near = [](Bgr a, Bgr b) {
    for (int i = 0; i < 3; ++i) {
      if (std::abs(int(a[i]) - int(b[i])) > 2) return false;
    }
    return true;
  };
  EXPECT_TRUE(near(YuvToBgr(81, 90, 240), Bgr{0, 0, 255}));     // red
  EXPECT_TRUE(near(YuvToBgr(145, 54, 34), Bgr{0, 255, 0}));     // green
  EXPECT_TRUE(near(YuvToBgr(41, 240, 110), Bgr{255, 0, 0}));    // blue
  EXPECT_TRUE(near(YuvToBgr(210, 16, 146), Bgr{0, 255, 255}));  // yellow
  // Out-of-range codes clamp.
  EXPECT_EQ(YuvToBgr(0, 128, 128), (Bgr{0, 0, 0}));
  EXPECT_EQ(YuvToBgr(255, 128, 128), (Bgr{255, 255, 255}));
  EXPECT_EQ(YuvToBgr(81, 90, 240), (Bgr{0, 0, 255}));  // exact in this fixed point
}

TEST(PixelConvert, YuyvAndUyvyShareChromaPerPairAndHonourTheStride) {
  // Two rows of 2 pixels, stride 6 (2 bytes of padding per row).
  const std::vector<std::uint8_t> yuyv = {81, 90,  126, 240, 0xEE, 0xEE,   // red-ish pair
                                          16, 128, 235, 128, 0xEE, 0xEE};  // black, white
  auto image = ConvertToBgr(yuyv, kFourCcYuyv, 2, 2, 6);
  ASSERT_TRUE(image.has_value()) << image.error().ToString();
  EXPECT_EQ(image->at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 255));
  const auto second = YuvToBgr(126, 90, 240);
  EXPECT_EQ(image->at<cv::Vec3b>(0, 1), cv::Vec3b(second[0], second[1], second[2]));
  EXPECT_EQ(image->at<cv::Vec3b>(1, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(image->at<cv::Vec3b>(1, 1), cv::Vec3b(255, 255, 255));
  const std::vector<std::uint8_t> uyvy = {90, 81, 240, 126};
  auto swapped = ConvertToBgr(uyvy, kFourCcUyvy, 2, 1, 0);
  ASSERT_TRUE(swapped.has_value());
  EXPECT_EQ(swapped->at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 255));
}

TEST(PixelConvert, GreyRgbAndBgr) {
  const std::vector<std::uint8_t> grey = {0, 77, 255};
  auto g = ConvertToBgr(grey, kFourCcGrey, 3, 1, 0);
  ASSERT_TRUE(g.has_value());
  EXPECT_EQ(g->at<cv::Vec3b>(0, 1), cv::Vec3b(77, 77, 77));
  const std::vector<std::uint8_t> rgb = {10, 20, 30};
  EXPECT_EQ(ConvertToBgr(rgb, kFourCcRgb24, 1, 1, 0)->at<cv::Vec3b>(0, 0), cv::Vec3b(30, 20, 10));
  EXPECT_EQ(ConvertToBgr(rgb, kFourCcBgr24, 1, 1, 0)->at<cv::Vec3b>(0, 0), cv::Vec3b(10, 20, 30));
}

TEST(PixelConvert, MjpegDecodesAndTruncatedFramesAreRejected) {
  cv::Mat source(48, 64, CV_8UC3, cv::Scalar(40, 120, 200));
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", source, jpeg));
  EXPECT_TRUE(IsCompleteJpeg(jpeg));
  std::vector<std::uint8_t> padded = jpeg;
  padded.resize(padded.size() + 100, 0);  // drivers pad with zeros
  EXPECT_TRUE(IsCompleteJpeg(padded));
  auto image = ConvertToBgr(padded, kFourCcMjpg, 64, 48, 0);
  ASSERT_TRUE(image.has_value()) << image.error().ToString();
  EXPECT_LT(cv::norm(*image, source, cv::NORM_INF), 8.0);
  std::vector<std::uint8_t> cut(jpeg.begin(), jpeg.begin() + jpeg.size() / 2);
  EXPECT_FALSE(IsCompleteJpeg(cut));
  auto truncated = ConvertToBgr(cut, kFourCcMjpg, 64, 48, 0);
  ASSERT_FALSE(truncated.has_value());
  EXPECT_NE(truncated.error().message.find("truncated"), std::string::npos);
  auto wrong_size = ConvertToBgr(jpeg, kFourCcMjpg, 32, 48, 0);
  EXPECT_FALSE(wrong_size.has_value());
}

TEST(PixelConvert, RejectsShortBuffersOddWidthsAndUnknownFormats) {
  const std::vector<std::uint8_t> few(10, 0);
  EXPECT_EQ(ConvertToBgr(few, kFourCcYuyv, 4, 4, 0).error().code, ErrorCode::kBadInput);
  EXPECT_EQ(ConvertToBgr(few, kFourCcYuyv, 3, 1, 0).error().code, ErrorCode::kBadInput);
  EXPECT_EQ(ConvertToBgr(few, FourCc('N', 'V', '1', '2'), 2, 2, 0).error().code,
            ErrorCode::kUnsupported);
  EXPECT_EQ(FourCcToString(kFourCcMjpg), "MJPG");
  EXPECT_EQ(*ParseFourCc("YUYV"), kFourCcYuyv);
  EXPECT_FALSE(ParseFourCc("YUV").has_value());
}

// --- The camera against the fake device ----------------------------------------------------

FakeV4l2::Options UvcOptions() {
  FakeV4l2::Options o;
  o.formats = {{kFourCcYuyv, {{640, 480}, {320, 240}}}, {kFourCcMjpg, {{1280, 720}, {640, 480}}}};
  o.frame_period_s = 0.02;
  return o;
}

V4l2Options CameraOptionsFor(const FakeV4l2& /*fake*/) {
  V4l2Options o;
  o.device = "/dev/fake-video0";
  o.width_px = 640;
  o.height_px = 480;
  o.lock_after_s = 0.0;
  return o;
}

std::unique_ptr<V4l2Camera> MakeCamera(std::shared_ptr<FakeV4l2> fake, const V4l2Options& o) {
  auto camera = V4l2Camera::Create(o, fake);
  EXPECT_TRUE(camera.has_value());
  return std::move(*camera);
}

bool Logged(const FakeV4l2& fake, const std::string& line) {
  const auto log = fake.log();
  return std::find(log.begin(), log.end(), line) != log.end();
}

TEST(V4l2Camera, NegotiatesThePreferredFormatAndSize) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  auto camera = MakeCamera(fake, CameraOptionsFor(*fake));
  auto format = camera->Start();
  ASSERT_TRUE(format.has_value()) << format.error().ToString();
  EXPECT_EQ(format->pixel_format, "YUYV");
  EXPECT_EQ(format->width_px, 640);
  EXPECT_EQ(format->height_px, 480);
  auto frame = camera->Capture(Clock::now(), 1s);
  ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
  EXPECT_EQ(frame->image.size(), cv::Size(640, 480));
  EXPECT_EQ(frame->image.type(), CV_8UC3);
}

TEST(V4l2Camera, FallsBackToTheNextFormatTheDeviceOffers) {
  FakeV4l2::Options fo = UvcOptions();
  fo.formats = {{kFourCcGrey, {{640, 480}}}, {kFourCcMjpg, {{1280, 720}}}};
  auto fake = std::make_shared<FakeV4l2>(fo);
  V4l2Options o = CameraOptionsFor(*fake);
  o.pixel_formats = {"YUYV", "MJPG", "GREY"};
  o.width_px = 1280;
  o.height_px = 720;
  auto camera = MakeCamera(fake, o);
  auto format = camera->Start();
  ASSERT_TRUE(format.has_value()) << format.error().ToString();
  EXPECT_EQ(format->pixel_format, "MJPG");  // YUYV is not offered
  auto frame = camera->Capture(Clock::now(), 1s);
  ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
  EXPECT_EQ(frame->image.size(), cv::Size(1280, 720));
}

TEST(V4l2Camera, ADriverThatSubstitutesTheFormatFallsThroughToTheNext) {
  FakeV4l2::Options fo = UvcOptions();
  fo.formats = {
      {kFourCcMjpg, {{640, 480}}}, {kFourCcYuyv, {{640, 480}}}, {kFourCcGrey, {{640, 480}}}};
  fo.substitute_fourcc = kFourCcYuyv;  // listed, but S_FMT answers MJPG
  auto fake = std::make_shared<FakeV4l2>(fo);
  V4l2Options o = CameraOptionsFor(*fake);
  o.pixel_formats = {"YUYV", "GREY"};
  auto camera = MakeCamera(fake, o);
  auto format = camera->Start();
  ASSERT_TRUE(format.has_value()) << format.error().ToString();
  EXPECT_EQ(format->pixel_format, "GREY");
  EXPECT_TRUE(Logged(*fake, "S_FMT MJPG 640x480"));  // the substitution was seen and skipped
}

TEST(V4l2Camera, AnAdjustedSizeIsAcceptedUnlessExact) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  V4l2Options o = CameraOptionsFor(*fake);
  o.pixel_formats = {"YUYV"};
  o.width_px = 1920;
  o.height_px = 1080;
  auto camera = MakeCamera(fake, o);
  auto format = camera->Start();
  ASSERT_TRUE(format.has_value());
  EXPECT_EQ(format->width_px, 640);  // the nearest the driver has
  camera->Stop();
  o.exact_size = true;
  auto exact = MakeCamera(fake, o)->Start();
  ASSERT_FALSE(exact.has_value());
  EXPECT_EQ(exact.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(exact.error().message.find("YUYV, MJPG"), std::string::npos) << exact.error().message;
  EXPECT_EQ(fake->open_fds(), 0);
}

TEST(V4l2Camera, RefusesANodeThatCannotCapture) {
  FakeV4l2::Options fo = UvcOptions();
  fo.capture_device = false;  // a UVC metadata node
  auto fake = std::make_shared<FakeV4l2>(fo);
  auto result = MakeCamera(fake, CameraOptionsFor(*fake))->Start();
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(result.error().message.find("metadata"), std::string::npos);
  EXPECT_EQ(fake->open_fds(), 0);
}

TEST(V4l2Camera, AMissingDeviceIsNoDevice) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  V4l2Options o = CameraOptionsFor(*fake);
  o.device = "/dev/v4l/by-id/usb-nothing-video-index0";
  auto result = MakeCamera(fake, o)->Start();
  ASSERT_FALSE(result.has_value());
  EXPECT_EQ(result.error().code, ErrorCode::kNoDevice);
}

TEST(V4l2Camera, SetsManualControlsAfterSwitchingAutoOff) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  fake->AddUvcControls();
  V4l2Options o = CameraOptionsFor(*fake);
  o.exposure_us = 10000;  // 100 x 100 us
  o.gain = 30;
  o.white_balance_k = 4000;
  o.focus = 20;
  auto camera = MakeCamera(fake, o);
  ASSERT_TRUE(camera->Start().has_value());
  EXPECT_EQ(fake->control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(fake->control(V4L2_CID_EXPOSURE_ABSOLUTE), 100);
  EXPECT_EQ(fake->control(V4L2_CID_EXPOSURE_AUTO_PRIORITY), 0);
  EXPECT_EQ(fake->control(V4L2_CID_AUTOGAIN), 0);
  EXPECT_EQ(fake->control(V4L2_CID_GAIN), 30);
  EXPECT_EQ(fake->control(V4L2_CID_AUTO_WHITE_BALANCE), 0);
  EXPECT_EQ(fake->control(V4L2_CID_WHITE_BALANCE_TEMPERATURE), 4000);
  EXPECT_EQ(fake->control(V4L2_CID_FOCUS_ABSOLUTE), 20);
  for (const std::string& line : fake->log()) {
    EXPECT_EQ(line.find("refused"), std::string::npos) << line;  // auto was always off first
  }
  const auto applied = camera->AppliedControls();
  EXPECT_EQ(applied.at("exposure"), 100);
  auto frame = camera->Capture(Clock::now(), 1s);
  ASSERT_TRUE(frame.has_value());
  EXPECT_DOUBLE_EQ(frame->exposure_us, 10000.0);
}

TEST(V4l2Camera, LocksWhatTheAutoModesSettledOn) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  fake->AddUvcControls();
  V4l2Options o = CameraOptionsFor(*fake);
  o.lock_after_s = 0.1;
  o.gain = 10;  // set by hand: not locked from auto
  auto camera = MakeCamera(fake, o);
  ASSERT_TRUE(camera->Start().has_value());
  EXPECT_EQ(fake->control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(fake->control(V4L2_CID_EXPOSURE_ABSOLUTE), 157);  // the fake's auto value
  EXPECT_EQ(fake->control(V4L2_CID_WHITE_BALANCE_TEMPERATURE), 5100);
  EXPECT_EQ(fake->control(V4L2_CID_GAIN), 10);
  EXPECT_EQ(fake->control(V4L2_CID_FOCUS_AUTO), 1);  // focus was not asked for
}

TEST(V4l2Camera, DropsBuffersExposedBeforeNotBefore) {
  for (const auto stamp : {FakeV4l2::Stamp::kStartOfExposure, FakeV4l2::Stamp::kEndOfFrame,
                           FakeV4l2::Stamp::kUnknown}) {
    FakeV4l2::Options fo = UvcOptions();
    fo.stamp = stamp;
    auto fake = std::make_shared<FakeV4l2>(fo);
    fake->AddUvcControls();
    V4l2Options o = CameraOptionsFor(*fake);
    o.exposure_us = 5000;
    auto camera = MakeCamera(fake, o);
    ASSERT_TRUE(camera->Start().has_value());
    std::this_thread::sleep_for(150ms);  // the table moves; every buffer fills with old frames
    const auto settled = Clock::now() + 30ms;
    auto frame = camera->Capture(settled, 1s);
    ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
    EXPECT_GE(frame->exposed, settled) << static_cast<int>(stamp);
    EXPECT_GE(camera->counters().stale_dropped, 4u) << static_cast<int>(stamp);
    if (stamp == FakeV4l2::Stamp::kStartOfExposure) {
      // The frame is the first exposed after `settled`, not a later one.
      EXPECT_LT(frame->exposed - settled, 20ms + 5ms);
    }
  }
}

TEST(V4l2Camera, CorruptAndTruncatedFramesAreSkipped) {
  FakeV4l2::Options fo = UvcOptions();
  fo.formats = {{kFourCcMjpg, {{320, 240}}}};
  auto fake = std::make_shared<FakeV4l2>(fo);
  V4l2Options o = CameraOptionsFor(*fake);
  o.pixel_formats = {"MJPG"};
  auto camera = MakeCamera(fake, o);
  ASSERT_TRUE(camera->Start().has_value());
  fake->FlagNextFramesAsErrors(2);
  auto frame = camera->Capture(Clock::now(), 1s);
  ASSERT_TRUE(frame.has_value());
  fake->TruncateNextJpegFrames(2);
  frame = camera->Capture(Clock::now(), 1s);
  ASSERT_TRUE(frame.has_value());
  EXPECT_GE(camera->counters().corrupt_dropped, 4u);
}

TEST(V4l2Camera, TimesOutAndReopensAfterRepeatedTimeouts) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  V4l2Options o = CameraOptionsFor(*fake);
  o.timeouts_before_reopen = 2;
  auto camera = MakeCamera(fake, o);
  ASSERT_TRUE(camera->Start().has_value());
  ASSERT_TRUE(camera->Capture(Clock::now(), 1s).has_value());
  fake->SetProducing(false);  // the camera stalls
  auto first = camera->Capture(Clock::now(), 120ms);
  ASSERT_FALSE(first.has_value());
  EXPECT_EQ(first.error().code, ErrorCode::kTimeout);
  EXPECT_EQ(fake->open_fds(), 1);
  auto second = camera->Capture(Clock::now(), 120ms);
  EXPECT_EQ(second.error().code, ErrorCode::kTimeout);
  EXPECT_EQ(fake->open_fds(), 0);  // closed after two timeouts in a row
  EXPECT_EQ(fake->mapped_buffers(), 0);
  fake->SetProducing(true);
  auto frame = camera->Capture(Clock::now(), 1s);
  ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
  EXPECT_EQ(camera->counters().reopened, 1u);
  EXPECT_EQ(fake->opens(), 2);
}

TEST(V4l2Camera, ALostDeviceIsNoDeviceThenReopensWhenItReturns) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  fake->AddUvcControls();
  V4l2Options o = CameraOptionsFor(*fake);
  o.exposure_us = 8000;
  auto camera = MakeCamera(fake, o);
  ASSERT_TRUE(camera->Start().has_value());
  ASSERT_TRUE(camera->Capture(Clock::now(), 1s).has_value());
  fake->Unplug();
  auto lost = camera->Capture(Clock::now(), 200ms);
  ASSERT_FALSE(lost.has_value());
  EXPECT_EQ(lost.error().code, ErrorCode::kNoDevice) << lost.error().ToString();
  EXPECT_NE(lost.error().message.find("plug it in again"), std::string::npos);
  // Torn down completely: no fd, no mapping left on the dead device.
  EXPECT_EQ(fake->open_fds(), 0);
  EXPECT_EQ(fake->mapped_buffers(), 0);
  fake->AddUvcControls();  // it comes back with its defaults (a USB reset)...
  fake->Replug();
  // ...and the manual controls are applied again.
  auto frame = camera->Capture(Clock::now(), 1s);
  ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
  EXPECT_EQ(camera->counters().reopened, 1u);
  EXPECT_EQ(fake->control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(fake->control(V4L2_CID_EXPOSURE_ABSOLUTE), 80);
  EXPECT_GE(camera->counters().device_lost, 1u);
}

TEST(V4l2Camera, ADeviceThatReturnsWithinTheTimeoutGivesAFrame) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  auto camera = MakeCamera(fake, CameraOptionsFor(*fake));
  ASSERT_TRUE(camera->Start().has_value());
  fake->Unplug();
  std::jthread replug([&] {
    std::this_thread::sleep_for(150ms);
    fake->Replug();
  });
  const auto asked = Clock::now();
  auto frame = camera->Capture(asked, 2s);
  ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
  EXPECT_GE(frame->exposed, asked);
  EXPECT_EQ(camera->counters().reopened, 1u);
}

TEST(V4l2Camera, StopReleasesEverythingAndAbortsAWaitingCapture) {
  auto fake = std::make_shared<FakeV4l2>(UvcOptions());
  auto camera = MakeCamera(fake, CameraOptionsFor(*fake));
  ASSERT_TRUE(camera->Start().has_value());
  EXPECT_EQ(fake->open_fds(), 1);
  EXPECT_EQ(fake->mapped_buffers(), 4);
  fake->SetProducing(false);
  std::jthread stopper([&] {
    std::this_thread::sleep_for(100ms);
    camera->Stop();
  });
  auto frame = camera->Capture(Clock::now(), 5s);
  ASSERT_FALSE(frame.has_value());
  EXPECT_EQ(frame.error().code, ErrorCode::kAborted);
  stopper.join();
  EXPECT_EQ(fake->open_fds(), 0);
  EXPECT_EQ(fake->mapped_buffers(), 0);
  EXPECT_EQ(camera->Capture(Clock::now(), 10ms).error().code, ErrorCode::kInternal);
}

TEST(V4l2Camera, ConfigErrorsAreReportedBeforeAnyDeviceAccess) {
  V4l2Options o;
  o.pixel_formats = {"YUV"};
  EXPECT_EQ(V4l2Camera::Create(o, nullptr).error().code, ErrorCode::kBadInput);
}

// A real device, when the machine has one: list it and grab a frame.
TEST(V4l2Hardware, ListsAndCapturesWhenADeviceExists) {
  if (!std::filesystem::exists("/dev/video0")) GTEST_SKIP() << "no /dev/video0 on this machine";
  auto sys = MakeKernelV4l2Sys();
  const auto devices = ListV4l2Devices(*sys);
  EXPECT_FALSE(devices.empty());
  V4l2Options o;
  o.device = "/dev/video0";
  o.lock_after_s = 0.5;
  auto camera = V4l2Camera::Create(o);
  ASSERT_TRUE(camera.has_value());
  auto format = (*camera)->Start();
  if (!format) GTEST_SKIP() << "cannot start /dev/video0: " << format.error().ToString();
  auto frame = (*camera)->Capture(Clock::now(), 5s);
  ASSERT_TRUE(frame.has_value()) << frame.error().ToString();
  EXPECT_FALSE(frame->image.empty());
}

}  // namespace
}  // namespace revolve::capture
