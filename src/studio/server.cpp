#include "studio/server.hpp"

// Eigen's headers (through the API) before httplib's: a system header it pulls in defines a
// macro that breaks Eigen's product kernels when it comes first.
#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "studio/api.hpp"

#include <httplib.h>

#include <filesystem>
#include <map>

namespace handskin {

namespace fs = std::filesystem;

namespace {
const char* mime_of(const std::string& name) {
  const std::string ext = fs::path(name).extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".png") return "image/png";
  if (ext == ".json") return "application/json";
  return "application/octet-stream";
}
}  // namespace

bool StudioOptions::IsValid(std::string* error) const {
  if (port < 0 || port > 65535) return *error = "--port must be in [0, 65535]", false;
  if (address.empty()) return *error = "--address must not be empty", false;
  return true;
}

struct StudioServer::Impl {
  StudioOptions options;
  StudioModel model;
  std::string glb;
  std::map<std::string, std::pair<std::string, std::string>> files;  // "/name" → (mime, bytes)
  httplib::Server server;
  Impl(const StudioOptions& o, RiggedSkin skin) : options(o), model(std::move(skin)) {}
};

namespace {
RiggedSkin checked_model(const StudioOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("studio", err);
  return read_skin_glb(o.model);
}
}  // namespace

StudioServer::StudioServer(const StudioOptions& o) : impl_(new Impl(o, checked_model(o))) {
  Impl& I = *impl_;
  I.glb = read_file(o.model);
  if (!fs::is_directory(o.web_dir) || !fs::exists(fs::path(o.web_dir) / "index.html"))
    throw InputError(o.web_dir, "the studio page is not built here (no index.html): build it with scripts/build.sh, or give --web");
  for (const auto& e : fs::directory_iterator(o.web_dir))
    if (e.is_regular_file())
      I.files["/" + e.path().filename().string()] = {mime_of(e.path().filename().string()), read_file(e.path().string())};
  I.files["/"] = I.files["/index.html"];

  auto& s = I.server;
  s.set_payload_max_length(kMaxBodyBytes);
  s.set_tcp_nodelay(true);  // small replies at once (Nagle + delayed ACK added ~40 ms a solve)
  const auto send = [](httplib::Response& res, const ApiResponse& r) {
    res.status = r.status;
    res.set_content(r.body, r.content_type.c_str());
  };
  s.Get("/api/dofs", [&I, send](const httplib::Request&, httplib::Response& res) { send(res, I.model.dofs()); });
  s.Get("/api/system", [&I, send](const httplib::Request&, httplib::Response& res) { send(res, I.model.system()); });
  s.Post("/api/solve", [&I, send](const httplib::Request& req, httplib::Response& res) { send(res, I.model.solve(req.body)); });
  s.Post("/api/animate", [&I, send](const httplib::Request& req, httplib::Response& res) { send(res, I.model.animate(req.body)); });
  s.Get("/model.glb", [&I](const httplib::Request&, httplib::Response& res) { res.set_content(I.glb, "model/gltf-binary"); });
  s.Get(".*", [&I](const httplib::Request& req, httplib::Response& res) {
    const auto it = I.files.find(req.path);
    if (it == I.files.end()) {
      res.status = 404;
      res.set_content(Json{{"error", "no such file: " + req.path}}.dump(), "application/json");
      return;
    }
    res.set_content(it->second.second, it->second.first.c_str());
  });
  // Anything else the library refuses (a body over the limit, a bad request line) gets the
  // same one-line JSON; an exception in a handler is a 500, never a crash.
  s.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return;
    const std::string what = res.status == 413 ? "the request body is over " + std::to_string(kMaxBodyBytes) + " bytes"
                                               : "HTTP " + std::to_string(res.status);
    res.set_content(Json{{"error", what}}.dump(), "application/json");
  });
  s.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    res.status = 500;
    res.set_content(Json{{"error", what}}.dump(), "application/json");
  });
}

StudioServer::~StudioServer() { delete impl_; }

void StudioServer::run(const std::function<void(int)>& on_listening) {
  Impl& I = *impl_;
  int port = I.options.port;
  if (port == 0) {
    port = I.server.bind_to_any_port(I.options.address);
    if (port < 0) throw InputError("--address", "cannot listen on " + I.options.address);
  } else if (!I.server.bind_to_port(I.options.address, port)) {
    throw InputError("--port", "cannot listen on " + I.options.address + ":" + std::to_string(port) + " (in use?)");
  }
  on_listening(port);
  I.server.listen_after_bind();
}

void StudioServer::stop() { impl_->server.stop(); }

}  // namespace handskin
