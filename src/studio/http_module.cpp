// libhandskin_http.so: cpp-httplib behind the studio (studio/http_module.hpp).
#include "studio/http_module.hpp"

#include <httplib.h>

#include <exception>
#include <new>

namespace {

struct Server {
  const handskin::HttpHandlers* handlers;
  httplib::Server http;
};

void answer(const handskin::HttpHandlers& h, const char* method, const httplib::Request& req, httplib::Response& res) {
  const handskin::HttpReply r = h.request(method, req.path, req.body);
  res.status = r.status;
  res.set_content(r.body, r.content_type.c_str());
}

}  // namespace

extern "C" void* handskin_http_create(const handskin::HttpHandlers* handlers, size_t max_body) {
  Server* s = new (std::nothrow) Server{handlers, {}};
  if (!s) return nullptr;
  httplib::Server& http = s->http;
  http.set_payload_max_length(max_body);
  http.set_tcp_nodelay(true);  // small replies at once (Nagle + delayed ACK added ~40 ms a solve)
  const handskin::HttpHandlers& h = *handlers;
  http.Get(".*", [&h](const httplib::Request& req, httplib::Response& res) { answer(h, "GET", req, res); });
  http.Post(".*", [&h](const httplib::Request& req, httplib::Response& res) { answer(h, "POST", req, res); });
  // Every status ≥ 400 passes here, a handler's too: only an empty body is filled.
  http.set_error_handler([&h](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return;
    res.set_content(h.error(res.status), "application/json");
  });
  http.set_exception_handler([&h](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    res.status = 500;
    res.set_content(h.internal_error(what), "application/json");
  });
  return s;
}

extern "C" int handskin_http_bind(void* server, const char* address, int port) {
  httplib::Server& http = static_cast<Server*>(server)->http;
  if (port == 0) return http.bind_to_any_port(address);
  return http.bind_to_port(address, port) ? port : -1;
}

extern "C" int handskin_http_listen(void* server) { return static_cast<Server*>(server)->http.listen_after_bind() ? 0 : 1; }

extern "C" void handskin_http_stop(void* server) { static_cast<Server*>(server)->http.stop(); }

extern "C" void handskin_http_destroy(void* server) { delete static_cast<Server*>(server); }
