#include "studio/server.hpp"

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "core/module.hpp"
#include "studio/api.hpp"
#include "studio/http_module.hpp"

#include <filesystem>
#include <map>
#include <memory>
#include <new>

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

namespace {

// The transport, loaded once (core/module.hpp; studio/http_module.hpp says why it is a module).
struct HttpModule {
  decltype(&handskin_http_create) create = nullptr;
  decltype(&handskin_http_bind) bind = nullptr;
  decltype(&handskin_http_listen) listen = nullptr;
  decltype(&handskin_http_stop) stop = nullptr;
  decltype(&handskin_http_destroy) destroy = nullptr;
  std::string failure;
};

const HttpModule& http_module() {
  static const HttpModule m = [] {
    HttpModule m;
    LoadedModule lib = open_module(HANDSKIN_HTTP_MODULE, "libhandskin_http.so");
    lib.entry(m.create, "handskin_http_create");
    lib.entry(m.bind, "handskin_http_bind");
    lib.entry(m.listen, "handskin_http_listen");
    lib.entry(m.stop, "handskin_http_stop");
    lib.entry(m.destroy, "handskin_http_destroy");
    m.failure = lib.failure;
    return m;
  }();
  return m;
}

}  // namespace

struct StudioServer::Impl {
  StudioOptions options;
  StudioModel model;
  std::string glb;
  std::map<std::string, std::pair<std::string, std::string>> files;  // "/name" → (mime, bytes)
  HttpHandlers handlers;
  const HttpModule* http = nullptr;
  void* server = nullptr;
  Impl(const StudioOptions& o, RiggedSkin skin) : options(o), model(std::move(skin)) {}
  ~Impl() {
    if (server) http->destroy(server);
  }
  HttpReply answer(const std::string& method, const std::string& path, const std::string& body) const {
    if (method == "POST") {
      if (path == "/api/solve") return model.solve(body);
      if (path == "/api/animate") return model.animate(body);
      return {404, "", "application/json"};  // the transport's "HTTP 404"
    }
    if (path == "/api/dofs") return model.dofs();
    if (path == "/api/system") return model.system();
    if (path == "/model.glb") return {200, glb, "model/gltf-binary"};
    const auto it = files.find(path);
    if (it == files.end()) return {404, Json{{"error", "no such file: " + path}}.dump(), "application/json"};
    return {200, it->second.second, it->second.first};
  }
};

namespace {
RiggedSkin checked_model(const StudioOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("studio", err);
  return read_skin_glb(o.model);
}
}  // namespace

StudioServer::StudioServer(const StudioOptions& o) : impl_(new Impl(o, checked_model(o))) {
  std::unique_ptr<Impl> owned(impl_);
  Impl& I = *impl_;
  I.glb = read_file(o.model);
  if (!fs::is_directory(o.web_dir) || !fs::exists(fs::path(o.web_dir) / "index.html"))
    throw InputError(o.web_dir, "the studio page is not built here (no index.html): build it with scripts/build.sh, or give --web");
  for (const auto& e : fs::directory_iterator(o.web_dir))
    if (e.is_regular_file())
      I.files["/" + e.path().filename().string()] = {mime_of(e.path().filename().string()), read_file(e.path().string())};
  I.files["/"] = I.files["/index.html"];

  I.http = &http_module();
  if (!I.http->failure.empty())
    throw InputError("studio", "the studio needs handskin's HTTP module (libhandskin_http.so, Debian's libcpp-httplib0.11), "
                               "which could not be loaded: " + I.http->failure);
  I.handlers.request = [&I](const std::string& method, const std::string& path, const std::string& body) {
    return I.answer(method, path, body);
  };
  // Anything else the transport refuses (a body over the limit, a bad request line) gets the
  // same one-line JSON; an exception in a handler is a 500, never a crash.
  I.handlers.error = [](int status) {
    const std::string what = status == 413 ? "the request body is over " + std::to_string(kMaxBodyBytes) + " bytes"
                                           : "HTTP " + std::to_string(status);
    return Json{{"error", what}}.dump();
  };
  I.handlers.internal_error = [](const std::string& what) { return Json{{"error", what}}.dump(); };
  I.server = I.http->create(&I.handlers, kMaxBodyBytes);
  if (!I.server) throw std::bad_alloc();
  owned.release();
}

StudioServer::~StudioServer() { delete impl_; }

void StudioServer::run(const std::function<void(int)>& on_listening) {
  Impl& I = *impl_;
  const int port = I.http->bind(I.server, I.options.address.c_str(), I.options.port);
  if (port < 0) {
    if (I.options.port == 0) throw InputError("--address", "cannot listen on " + I.options.address);
    throw InputError("--port", "cannot listen on " + I.options.address + ":" + std::to_string(I.options.port) + " (in use?)");
  }
  on_listening(port);
  I.http->listen(I.server);
}

void StudioServer::stop() { impl_->http->stop(impl_->server); }

}  // namespace handskin
