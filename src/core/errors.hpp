#pragma once
/// Error kinds shared by every stage.
///  - InputError: bad user input (a file, a key, an option). The CLI prints it as one line
///    `error: <where>: <what>` and exits non-zero.
///  - GateFailure: a quality gate failed under --strict (exit 3; nothing was written).
///  - InternalError: a broken invariant (a bug), raised by HS_CHECK with file and line (exit 4).
#include <stdexcept>
#include <string>

namespace handskin {

/// For an options struct's IsValid(std::string* error): `message` into *error (when given),
/// and false — so that a check reads `if (!(x > 0)) return invalid(error, "x must be > 0");`.
inline bool invalid(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

class InputError : public std::runtime_error {
 public:
  /// `where` names the file, option or key at fault; `what` says what is wrong with it.
  InputError(std::string where, std::string what);
  const std::string& where() const { return where_; }
  const std::string& detail() const { return detail_; }

 private:
  std::string where_;
  std::string detail_;
};

/// Bad usage: a flag missing, a flag's value that is not one of its choices or not of its
/// form, flags that do not go together (exit 2; InputError is bad data, exit 1). `where` names
/// the flag or the command.
class UsageError : public InputError {
 public:
  using InputError::InputError;
};

/// A quality gate failed under --strict: the command wrote nothing (exit 3).
class GateFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class InternalError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

[[noreturn]] void fail_check(const char* cond, const char* file, int line, const std::string& msg);

}  // namespace handskin

/// Invariant check that stays in release builds (a bare assert would vanish).
#define HS_CHECK(cond, msg)                                                   \
  do {                                                                        \
    if (!(cond)) ::handskin::fail_check(#cond, __FILE__, __LINE__, (msg));    \
  } while (0)
