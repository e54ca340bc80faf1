// Status values for everything that reads files or user input (Draco-style).
// Algorithms assert their preconditions instead; only main() turns a Status
// into an exit code.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace raylod {

class [[nodiscard]] Status {
 public:
  Status() = default;  // ok
  static Status ok() { return {}; }
  static Status error(std::string message) { return Status(std::move(message)); }

  bool is_ok() const { return !message_.has_value(); }
  explicit operator bool() const { return is_ok(); }
  const std::string& message() const {
    static const std::string kOk = "ok";
    return message_ ? *message_ : kOk;
  }
  // Prefixes context, e.g. the file name: "teapot.ply: line 12: bad vertex".
  Status with_context(const std::string& context) const {
    return is_ok() ? *this : Status(context + ": " + *message_);
  }

 private:
  explicit Status(std::string m) : message_(std::move(m)) {}
  std::optional<std::string> message_;
};

template <class T>
class [[nodiscard]] StatusOr {
 public:
  StatusOr(T value) : v_(std::move(value)) {}
  StatusOr(Status status) : v_(std::move(status)) {}

  bool is_ok() const { return std::holds_alternative<T>(v_); }
  explicit operator bool() const { return is_ok(); }
  Status status() const { return is_ok() ? Status::ok() : std::get<Status>(v_); }
  T& value() & { return std::get<T>(v_); }
  const T& value() const& { return std::get<T>(v_); }
  T&& value() && { return std::get<T>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace raylod

#define RAYLOD_CONCAT_INNER(a, b) a##b
#define RAYLOD_CONCAT(a, b) RAYLOD_CONCAT_INNER(a, b)

#define RAYLOD_RETURN_IF_ERROR(expr)               \
  do {                                             \
    ::raylod::Status _raylod_status = (expr);      \
    if (!_raylod_status.is_ok()) return _raylod_status; \
  } while (0)

// RAYLOD_ASSIGN_OR_RETURN(auto x, make_x());
#define RAYLOD_ASSIGN_OR_RETURN(lhs, expr)                                   \
  auto RAYLOD_CONCAT(_raylod_or_, __LINE__) = (expr);                        \
  if (!RAYLOD_CONCAT(_raylod_or_, __LINE__).is_ok())                         \
    return RAYLOD_CONCAT(_raylod_or_, __LINE__).status();                    \
  lhs = std::move(RAYLOD_CONCAT(_raylod_or_, __LINE__).value())
