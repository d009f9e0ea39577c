#pragma once
// The tirstrain::Error a call throws, for tests that check its message and context; a test failure when it
// throws none.
#include <gtest/gtest.h>

#include <functional>

#include "core/error.hpp"

namespace tirstrain::testing {

inline Error expect_error(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "expected tirstrain::Error";
  return Error("none");
}

}  // namespace tirstrain::testing
