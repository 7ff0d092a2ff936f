#pragma once
/// `handskin studio`: a local web server for the hand studio (docs/studio.md), its transport
/// cpp-httplib (Debian's libcpp-httplib-dev) in the module libhandskin_http.so
/// (studio/http_module.hpp). It serves the model (`/model.glb`), the JSON API (studio/api.hpp)
/// and the page's files, which are read once at start-up from `web_dir` into memory and served
/// by exact name only: a request names a file of that list or gets 404, so no path (`..`,
/// percent-encoded or not) can reach anything else.
#include <functional>
#include <string>

namespace handskin {

struct StudioOptions {
  std::string model;               ///< skin.glb
  std::string address = "127.0.0.1";
  int port = 8080;                 ///< 0: any free port
  std::string web_dir;             ///< the page's built files (index.html, studio.js)
  bool IsValid(std::string* error) const;
};

/// Loads everything (the model, the page) and throws InputError naming what fails before it
/// listens; then calls `on_listening(port)` and serves until `stop()` is called (or forever).
class StudioServer {
 public:
  explicit StudioServer(const StudioOptions& options);
  ~StudioServer();
  StudioServer(const StudioServer&) = delete;
  StudioServer& operator=(const StudioServer&) = delete;
  /// Binds (InputError when the address or port cannot be bound) and serves; blocks.
  void run(const std::function<void(int port)>& on_listening);
  void stop();

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace handskin
