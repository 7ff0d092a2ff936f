// The hand studio's API and server (issue 16, first part): every malformed request gets a 4xx
// and one line, the server serves only its own files and keeps serving.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <thread>

#include "core/json_util.hpp"
#include "studio/api.hpp"
#include "studio/server.hpp"
#include "test_util.hpp"

#include <httplib.h>  // after Eigen's headers (see studio/server.cpp)

using namespace handskin;

namespace {
const std::string kBin = HANDSKIN_BINARY;

const StudioModel& model() {
  static const StudioModel m(read_skin_glb(test::default_fixture_run() + "/skin.glb"));
  return m;
}

void expect_refused(const std::string& body, int status, const std::string& says) {
  const ApiResponse r = model().solve(body);
  EXPECT_EQ(r.status, status) << body.substr(0, 80);
  const Json j = Json::parse(r.body);
  ASSERT_TRUE(j.contains("error")) << r.body;
  const std::string e = j["error"];
  EXPECT_NE(e.find(says), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
}

void expect_animate_refused(const std::string& body, int status, const std::string& says) {
  const ApiResponse r = model().animate(body);
  EXPECT_EQ(r.status, status) << body.substr(0, 80) << " -> " << r.body;
  const Json j = Json::parse(r.body, nullptr, false);
  ASSERT_TRUE(j.is_object() && j.contains("error")) << r.body;
  EXPECT_NE(j["error"].get<std::string>().find(says), std::string::npos) << j["error"];
  EXPECT_EQ(j["error"].get<std::string>().find('\n'), std::string::npos);
}
}  // namespace

TEST(Studio, DofsListsAllThirtyFiveWithTheirLimits) {
  const ApiResponse r = model().dofs();
  ASSERT_EQ(r.status, 200);
  const Json j = Json::parse(r.body);
  ASSERT_EQ(j["dofs"].size(), 35u);
  EXPECT_EQ(j["parameter_set"], "anatomical");
  for (const auto& d : j["dofs"]) {
    EXPECT_LE(d["min"].get<double>(), d["relaxed"].get<double>()) << d;
    EXPECT_LE(d["relaxed"].get<double>(), d["max"].get<double>()) << d;
  }
}

TEST(Studio, SolveAnswersEveryDofAndTheJointsAndAnInputMovesTheOtherFingers) {
  const Json relaxed = Json::parse(model().solve("{}").body);
  const ApiResponse r = model().solve(R"({"inputs": {"L2.flex": 80}, "targets": {"I3.flex": {"deg": 30, "weight": 2}}})");
  ASSERT_EQ(r.status, 200) << r.body;
  const Json j = Json::parse(r.body);
  EXPECT_EQ(j["angles"].size(), 35u);
  EXPECT_EQ(j["joints"].size(), 25u);
  EXPECT_DOUBLE_EQ(j["angles"]["little.mcp.flex"].get<double>(), 80.0);
  EXPECT_GT(std::abs(j["angles"]["ring.mcp.flex"].get<double>() - relaxed["angles"]["ring.mcp.flex"].get<double>()), 5.0);
  for (const auto& [name, n] : j["joints"].items()) {
    ASSERT_EQ(n["q"].size(), 4u) << name;
    double norm = 0;
    for (const auto& q : n["q"]) norm += q.get<double>() * q.get<double>();
    EXPECT_NEAR(norm, 1.0, 1e-9) << name;
  }
}

TEST(Studio, SystemGivesThePotentialThePageSolvesAndTheJointsItPoses) {
  // For the page's own solver: at the server's answer x (no DOF at a limit, nothing pinned),
  // the free DOFs satisfy Hx = g, and ½xᵀHx − gᵀx + c is the server's potential; the rest
  // transforms are the glb's nodes at the scan posture.
  const Json sys = Json::parse(model().system().body);
  ASSERT_EQ(sys["dofs"], 35);
  ASSERT_EQ(sys["joints"].size(), 25u);
  std::vector<std::string> names;
  const Json dof_list = Json::parse(model().dofs().body);
  for (const auto& d : dof_list["dofs"]) names.push_back(d["name"]);
  for (const char* set : {"model", "anatomical", "thesis"}) {
    SCOPED_TRACE(set);
    const Json& m = sys["sets"][set];
    ASSERT_TRUE(m["linear"].get<bool>());
    const std::vector<double> H = m["H"], g = m["g"];
    ASSERT_EQ(H.size(), 35u * 35u);
    for (int i = 0; i < 35; ++i)
      for (int k = 0; k < 35; ++k) EXPECT_DOUBLE_EQ(H[i * 35 + k], H[k * 35 + i]);
    const Json r = Json::parse(model().solve(std::string(R"({"torques": {"index.mcp.flex": 5}, "parameter_set": ")") + set + "\"}").body);
    std::vector<double> x;
    for (const auto& n : names) x.push_back(r["angles"][n]);
    double e = m["c"].get<double>() - 5 * x[dof_index("index.mcp.flex").value()];
    for (int i = 0; i < 35; ++i) {
      double hx = 0;
      for (int k = 0; k < 35; ++k) hx += H[i * 35 + k] * x[k];
      e += 0.5 * x[i] * hx - g[i] * x[i];
      const bool at_limit = x[i] <= m["lo"][i].get<double>() + 1e-9 || x[i] >= m["hi"][i].get<double>() - 1e-9;
      if (!at_limit) {
        EXPECT_NEAR(hx, g[i] + (names[i] == "index.mcp.flex" ? 5 : 0), 1e-9) << names[i];
      }
    }
    EXPECT_NEAR(e, r["energy"].get<double>(), 1e-9);
  }
  const auto rest = joint_nodes(Skeleton(model().skin().rig), Angles{});
  for (int j = 0; j < 25; ++j) {
    const Json& J = sys["joints"][j];
    EXPECT_EQ(J["name"], joints()[j].name);
    for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(J["rest"]["t"][k].get<double>(), rest[j].translation[k]);
    for (int k = 0; k < 4; ++k) EXPECT_DOUBLE_EQ(J["rest"]["q"][k].get<double>(), rest[j].rotation[k]);
    if (J["flex"].get<int>() >= 0) {
      EXPECT_EQ(dofs()[J["flex"].get<int>()].joint, j);
    }
  }
}

TEST(Studio, MalformedRequestsGetAFourHundredAndOneLine) {
  expect_refused("{\"inputs\":", 400, "not JSON");
  expect_refused("[1, 2]", 400, "must be a JSON object");
  expect_refused(R"({"inputs": {"Q9.flex": 10}})", 400, "unknown DOF 'Q9.flex'");
  expect_refused(R"({"inputs": {"L2.flex": "ten"}})", 400, "inputs.L2.flex must be a number");
  expect_refused(R"({"inputs": {"L2.flex": null}})", 400, "must be a number");
  expect_refused(R"({"inputs": {"L2.flex": 500}})", 422, "outside its limits");
  expect_refused(R"({"inputs": {"L2.flex": 1e400}})", 400, "not JSON");  // not a double: the parser refuses it
  expect_refused(R"({"inputs": [1]})", 400, "\"inputs\" must be an object");
  expect_refused(R"({"torques": {"L2.flex": 1e9}})", 422, "beyond");
  expect_refused(R"({"targets": {"L2.flex": {"deg": 10, "spin": 1}}})", 400, "unknown key \"spin\"");
  expect_refused(R"({"targets": {"L2.flex": {"weight": 1}}})", 400, "needs \"deg\"");
  expect_refused(R"({"pins": {}})", 400, "unknown key \"pins\"");
  expect_refused(std::string(200, '[') + std::string(200, ']'), 400, "nests deeper than 8");
  expect_refused("{\"inputs\": {\"L2.flex\": 1" + std::string(kMaxBodyBytes, ' ') + "}}", 413, "at most 65536");
}

TEST(Studio, AnimateGivesFramesAGlbOrACsvAndRefusesBadKeys) {
  const std::string keys = R"("keys": [{"time": 0, "angles": {"L2.flex": 0}}, {"time": 1, "angles": {"L2.flex": 80}}])";
  const ApiResponse f = model().animate("{" + keys + R"(, "fps": 10, "inputs_only": true})");
  ASSERT_EQ(f.status, 200) << f.body;
  const Json j = Json::parse(f.body);
  ASSERT_EQ(j["frames"].size(), 11u);
  EXPECT_EQ(j["times"].back().get<double>(), 1.0);
  EXPECT_EQ(j["joint_names"].size(), 25u);
  EXPECT_EQ(j["frames"][0]["joints"].size(), 25u);
  const int l2 = dof_index("little.mcp.flex").value(), r2 = dof_index("ring.mcp.flex").value();
  EXPECT_NEAR(j["frames"].back()["angles"][l2].get<double>(), 80, 1e-9);
  EXPECT_GT(j["frames"].back()["angles"][r2].get<double>(), j["frames"][0]["angles"][r2].get<double>() + 5);  // the solver filled in
  const ApiResponse g = model().animate("{" + keys + R"(, "format": "glb"})");
  ASSERT_EQ(g.status, 200);
  EXPECT_EQ(g.content_type, "model/gltf-binary");
  EXPECT_EQ(g.body.substr(0, 4), "glTF");
  EXPECT_NE(g.body.find("\"animations\""), std::string::npos);
  const ApiResponse c = model().animate("{" + keys + R"(, "format": "csv", "fps": 2})");
  ASSERT_EQ(c.status, 200);
  EXPECT_EQ(c.body.substr(0, 14), "time,wrist.tx,");
  EXPECT_EQ(std::count(c.body.begin(), c.body.end(), '\n'), 4);
  // Bad keys: a 4xx and one line; the server's state is untouched.
  expect_animate_refused(R"({"keys": 3})", 400, "\"keys\" must be an array");
  expect_animate_refused(R"({"keys": [{"time": 0}]})", 422, "2 to 500 keys");
  expect_animate_refused(R"({"keys": [{"time": 1}, {"time": 1}]})", 422, "keys[1].time must be after");
  expect_animate_refused(R"({"keys": [{"time": 0, "angles": {"toe": 1}}, {"time": 1}]})", 400, "unknown DOF 'toe'");
  expect_animate_refused(R"({"keys": [{"time": 0, "angles": {"L2.flex": 500}}, {"time": 1}]})", 422, "outside its limits");
  expect_animate_refused(R"({"keys": [{"time": 0, "angles": {"L2.flex": "x"}}, {"time": 1}]})", 400, "must be a number");
  expect_animate_refused(R"({"keys": [{"time": 0}, {"time": 1e300}]})", 422, "[0, 3600]");
  expect_animate_refused(R"({"keys": [{"time": 0}, {"time": 3000}], "fps": 60})", 422, "more than 3600 frames");
  expect_animate_refused("{" + keys + R"(, "fps": 0})", 422, "fps = 0");
  expect_animate_refused("{" + keys + R"(, "format": "gif"})", 400, "format must be");
  expect_animate_refused("{" + keys + R"(, "loop": true})", 400, "unknown key \"loop\"");
  expect_animate_refused(R"({"keys": [{"time": 0, "angles": {"L2.flex": 0}}, {"time": 1, "angles": {"I2.flex": 5}}], "inputs_only": true})",
                         422, "keys[0] gives no index.mcp.flex");
  expect_animate_refused(R"({"keys": [{"time": 0, "when": 1}, {"time": 1}]})", 400, "unknown key \"when\"");
}

TEST(Studio, ARequestMayNameAnotherParameterSetAndTorques) {
  const Json d = Json::parse(model().dofs().body);
  EXPECT_EQ(d["parameter_sets"], Json::array({"model", "anatomical", "thesis"}));
  const ApiResponse own = model().solve(R"({"torques": {"index.mcp.flex": 20}})");
  const ApiResponse thesis = model().solve(R"({"torques": {"index.mcp.flex": 20}, "parameter_set": "thesis"})");
  ASSERT_EQ(own.status, 200);
  ASSERT_EQ(thesis.status, 200);
  const Json a = Json::parse(own.body)["angles"], b = Json::parse(thesis.body)["angles"];
  double differ = 0;
  for (auto it = a.begin(); it != a.end(); ++it) differ += std::abs(it.value().get<double>() - b[it.key()].get<double>());
  EXPECT_GT(differ, 1.0);
  const ApiResponse relaxed = model().solve("{}");
  EXPECT_GT(a["index.mcp.flex"].get<double>(), Json::parse(relaxed.body)["angles"]["index.mcp.flex"].get<double>() + 5);  // the torque turns it
  expect_refused(R"({"parameter_set": "mine"})", 400, "unknown parameter_set \"mine\" (model, anatomical, thesis)");
  expect_refused(R"({"parameter_set": 3})", 400, "parameter_set must be a string");
  expect_animate_refused(R"({"keys": [{"time": 0}, {"time": 1}], "parameter_set": "mine"})", 400, "unknown parameter_set");
}

TEST(Studio, ServerServesOnlyItsOwnFilesAndKeepsServing) {
  const std::string web = test::temp_dir("studio-web");
  test::write_text(web + "/index.html", "<!doctype html><title>t</title>");
  test::write_text(web + "/studio.js", "console.log(1)");
  StudioOptions o;
  o.model = test::default_fixture_run() + "/skin.glb";
  o.port = 0;
  o.web_dir = web;
  StudioServer server(o);
  int port = -1;
  std::thread t([&] { server.run([&](int p) { port = p; }); });
  for (int k = 0; k < 500 && port < 0; ++k) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_GT(port, 0);
  httplib::Client c("127.0.0.1", port);
  EXPECT_EQ(c.Get("/")->status, 200);
  EXPECT_EQ(c.Get("/studio.js")->status, 200);
  EXPECT_EQ(c.Get("/model.glb")->body.size(), std::filesystem::file_size(o.model));
  for (const char* path : {"/../../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/..%2f..%2fetc%2fpasswd", "/index.html/../../x",
                           "/api/../../etc/hostname", "//etc/passwd"}) {
    const auto r = c.Get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, 404) << path;
    EXPECT_EQ(r->body.find("root:"), std::string::npos) << path;
  }
  const auto big = c.Post("/api/solve", std::string(kMaxBodyBytes + 10, ' '), "application/json");
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 413);
  EXPECT_NE(big->body.find("over 65536"), std::string::npos) << big->body;
  const auto bad = c.Post("/api/solve", "{nope", "application/json");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);
  const auto good = c.Post("/api/solve", R"({"inputs": {"L2.flex": 60}})", "application/json");  // still serving
  ASSERT_TRUE(good);
  EXPECT_EQ(good->status, 200);
  EXPECT_EQ(c.Get("/api/dofs")->status, 200);
  EXPECT_EQ(c.Get("/api/system")->status, 200);
  // What nothing serves is a 404 with one line of JSON, whichever the method.
  const auto post_file = c.Post("/index.html", "{}", "application/json");
  ASSERT_TRUE(post_file);
  EXPECT_EQ(post_file->status, 404);
  EXPECT_EQ(post_file->body, R"({"error":"HTTP 404"})");
  const auto get_api = c.Get("/api/solve");
  ASSERT_TRUE(get_api);
  EXPECT_EQ(get_api->status, 404);
  EXPECT_EQ(get_api->body, R"({"error":"no such file: /api/solve"})");
  const auto del = c.Delete("/api/dofs");
  ASSERT_TRUE(del);
  EXPECT_EQ(del->status, 404);
  EXPECT_EQ(del->body, R"({"error":"HTTP 404"})");
  EXPECT_EQ(c.Get("/model.glb")->get_header_value("Content-Type"), "model/gltf-binary");
  EXPECT_EQ(c.Get("/studio.js")->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  server.stop();
  t.join();
}

TEST(Studio, AModelThatDoesNotLoadStopsTheStudioBeforeItListens) {
  std::string out;
  const std::string dir = test::temp_dir("studio-bad");
  test::write_text(dir + "/x.glb", "not a glb");
  EXPECT_EQ(test::run(kBin + " -q studio --skin " + dir + "/x.glb --port 0", &out), 1);
  EXPECT_NE(out.find("not a readable glb"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  EXPECT_EQ(test::run(kBin + " -q studio --skin " + test::default_fixture_run() + "/skin.glb --port 0 --web " + dir, &out), 1);
  EXPECT_NE(out.find("the studio page is not built here"), std::string::npos) << out;
  EXPECT_EQ(test::run(kBin + " -q studio --skin " + test::default_fixture_run() + "/skin.glb --port 70000", &out), 2);
}
