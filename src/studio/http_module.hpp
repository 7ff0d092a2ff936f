#pragma once
/// The interface of libhandskin_http.so (http_module.cpp), the studio's HTTP transport, loaded
/// by studio/server.cpp when `handskin studio` starts. cpp-httplib (Debian's libcpp-httplib-dev)
/// is a shared library that brings OpenSSL, brotli and zlib: linked into the program, their
/// loading and relocation were part of every command's start though only the studio serves
/// HTTP. The module only moves requests and replies: what a request gets is decided by the
/// program's handlers (the API and the page's files stay in the program and are tested
/// without a socket). Both sides are built together, so C++ types cross the boundary.
#include <cstddef>
#include <functional>
#include <string>

namespace handskin {

struct HttpReply {
  int status = 200;
  std::string body;  ///< JSON, unless content_type says otherwise
  std::string content_type = "application/json";
};

struct HttpHandlers {
  /// Every GET (and HEAD) and POST request: method ("GET", "POST"), path, body. A reply of
  /// status ≥ 400 with an empty body is completed by `error`.
  std::function<HttpReply(const std::string& method, const std::string& path, const std::string& body)> request;
  /// The body of an error the transport makes (404 for a method nothing serves, 413 for a body
  /// over the limit, 400 for a bad request line) or a handler left empty.
  std::function<std::string(int status)> error;
  /// The body of a 500 when a handler throws (the exception's message).
  std::function<std::string(const std::string& what)> internal_error;
};

}  // namespace handskin

extern "C" {
/// A server that calls `handlers` (which must outlive it) and refuses bodies over `max_body`
/// bytes; nullptr only when memory runs out.
void* handskin_http_create(const handskin::HttpHandlers* handlers, size_t max_body);
/// Binds `address`: `port`, or any free port when it is 0. Returns the port, or -1.
int handskin_http_bind(void* server, const char* address, int port);
/// Serves on the bound socket until handskin_http_stop; returns 0 when stopped cleanly.
int handskin_http_listen(void* server);
/// Stops a listening server (from any thread).
void handskin_http_stop(void* server);
void handskin_http_destroy(void* server);
}
