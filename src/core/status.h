// Status values for everything that reads files or user input (Draco-style).
// Algorithms assert their preconditions instead; only main() turns a Status
// into an exit code.
#pragma once

#include <cerrno>
#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace raylod {

// What kind of failure a Status is, for code that acts on it (people read
// the message; code never parses it).
enum class StatusCode {
  kOk,
  kError,        // any other failure
  kWriteFailed,  // an output file could not be created, written, flushed or renamed into place
  kNoSpace,      // the same, because its file system is full (ENOSPC, EDQUOT)
};

class [[nodiscard]] Status {
 public:
  Status() = default;  // ok
  static Status ok() { return {}; }
  static Status error(std::string message) { return Status(StatusCode::kError, std::move(message), {}); }
  // Writing the output file `path` failed; `err` is the errno if known (0
  // otherwise): ENOSPC and EDQUOT make it kNoSpace, anything else kWriteFailed.
  static Status write_failed(std::string path, std::string message, int err = 0);

  bool is_ok() const { return code_ == StatusCode::kOk; }
  explicit operator bool() const { return is_ok(); }
  StatusCode code() const { return code_; }
  // kWriteFailed or kNoSpace.
  bool is_write_failure() const { return code_ == StatusCode::kWriteFailed || code_ == StatusCode::kNoSpace; }
  // The output file a write failure is about; empty for other statuses.
  const std::string& path() const { return path_; }
  const std::string& message() const {
    static const std::string kOk = "ok";
    return message_ ? *message_ : kOk;
  }
  // Prefixes context, e.g. the file name: "teapot.ply: line 12: bad vertex".
  // The code and path stay.
  Status with_context(const std::string& context) const {
    return is_ok() ? *this : Status(code_, context + ": " + *message_, path_);
  }

 private:
  Status(StatusCode code, std::string m, std::string path)
      : code_(code), message_(std::move(m)), path_(std::move(path)) {}
  StatusCode code_ = StatusCode::kOk;
  std::optional<std::string> message_;
  std::string path_;
};

inline Status Status::write_failed(std::string path, std::string message, int err) {
  const bool no_space = err == ENOSPC || err == EDQUOT;
  return Status(no_space ? StatusCode::kNoSpace : StatusCode::kWriteFailed, std::move(message), std::move(path));
}

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
