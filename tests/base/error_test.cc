#include "base/error.h"

#include <set>
#include <string>

#include <gtest/gtest.h>

namespace revolve {
namespace {

TEST(Error, CodeNamesAreStableAndDistinct) {
  EXPECT_EQ(ToString(ErrorCode::kBadInput), "bad_input");
  EXPECT_EQ(ToString(ErrorCode::kNotFound), "not_found");
  EXPECT_EQ(ToString(ErrorCode::kIo), "io");
  EXPECT_EQ(ToString(ErrorCode::kTimeout), "timeout");
  EXPECT_EQ(ToString(ErrorCode::kLinkDown), "link_down");
  EXPECT_EQ(ToString(ErrorCode::kNoDevice), "no_device");
  EXPECT_EQ(ToString(ErrorCode::kStalled), "stalled");
  EXPECT_EQ(ToString(ErrorCode::kAlarm), "alarm");
  EXPECT_EQ(ToString(ErrorCode::kProtocol), "protocol");
  EXPECT_EQ(ToString(ErrorCode::kAborted), "aborted");
  EXPECT_EQ(ToString(ErrorCode::kBusy), "busy");
  EXPECT_EQ(ToString(ErrorCode::kUnsupported), "unsupported");
  EXPECT_EQ(ToString(ErrorCode::kInternal), "internal");
  std::set<std::string_view> names;
  for (int code = static_cast<int>(ErrorCode::kBadInput);
       code <= static_cast<int>(ErrorCode::kInternal); ++code) {
    names.insert(ToString(static_cast<ErrorCode>(code)));
  }
  EXPECT_EQ(names.size(), static_cast<std::size_t>(ErrorCode::kInternal) + 1);
}

TEST(Error, ToStringJoinsCodeAndMessage) {
  const Error error{ErrorCode::kTimeout, "the move to 10 deg did not finish"};
  EXPECT_EQ(error.ToString(), "timeout: the move to 10 deg did not finish");
  EXPECT_EQ(Error{}.code, ErrorCode::kInternal);
}

TEST(Error, MakeErrorAndWithContext) {
  Expected<int> value = MakeError(ErrorCode::kNotFound, "a.toml: config file not found");
  ASSERT_FALSE(value);
  EXPECT_EQ(value.error().code, ErrorCode::kNotFound);
  const Error wrapped = WithContext(value.error(), "while loading the rig");
  EXPECT_EQ(wrapped.code, ErrorCode::kNotFound);
  EXPECT_EQ(wrapped.ToString(), "not_found: while loading the rig: a.toml: config file not found");
  Expected<void> ok;
  EXPECT_TRUE(ok);
}

}  // namespace
}  // namespace revolve
