#include "core/errors.hpp"

namespace handskin {

InputError::InputError(std::string where, std::string what)
    : std::runtime_error(where + ": " + what), where_(std::move(where)), detail_(std::move(what)) {}

void fail_check(const char* cond, const char* file, int line, const std::string& msg) {
  throw InternalError(std::string("internal error at ") + file + ":" + std::to_string(line) + ": " + msg +
                      " (check `" + cond + "` failed)");
}

}  // namespace handskin
