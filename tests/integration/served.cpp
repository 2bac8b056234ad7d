#include "integration/served.hpp"

#include <fmt/format.h>

#include <chrono>
#include <regex>
#include <stdexcept>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

namespace strata::test {

namespace fs = std::filesystem;
using nlohmann::json;

int connect_to(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(std::uint16_t(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) throw std::runtime_error("connect failed");
  return fd;
}

std::string raw_exchange(int port, const std::string& request) {
  const int fd = connect_to(port);
  if (::send(fd, request.data(), request.size(), 0) != ssize_t(request.size())) throw std::runtime_error("send failed");
  timeval tv{5, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string answer;
  char buf[4096];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) {
    answer.append(buf, std::size_t(n));
    if (answer.find("\r\n\r\n") != std::string::npos && answer.find("}}") != std::string::npos) break;
  }
  ::close(fd);
  return answer;
}

std::string percent_encoded(const std::string& text) {
  std::string out;
  for (const unsigned char ch : text) {
    if (std::isalnum(ch) || ch == '-' || ch == '.' || ch == '_' || ch == '~') {
      out += char(ch);
    } else {
      out += fmt::format("%{:02X}", ch);
    }
  }
  return out;
}

namespace {
std::vector<std::string> serve_args(const fs::path& site, std::vector<std::string> args) {
  std::vector<std::string> all = {"serve", site.string(), "--listen", "127.0.0.1:0"};
  all.insert(all.end(), args.begin(), args.end());
  return all;
}
httplib::Result answered(httplib::Result r, const std::string& path) {
  if (!r) throw std::runtime_error("POST " + path + ": no answer: " + httplib::to_string(r.error()));
  return r;
}
}  // namespace

Served::Served(const fs::path& scratch, const fs::path& site, std::vector<std::string> args)
    : process_(scratch, serve_args(site, std::move(args))) {
  const fs::path out = process_.stdout_path();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(kServeStartTimeout_s);
  std::smatch m;
  static const std::regex line(R"(on http://127\.0\.0\.1:(\d+)/)");
  while (std::chrono::steady_clock::now() < deadline && process_.running()) {
    const std::string text = read_text(out);
    if (std::regex_search(text, m, line)) {
      port_ = std::stoi(m[1]);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (port_ == 0) {
    throw std::runtime_error("strata serve did not start: " + read_text(out) + read_text(process_.stderr_path()));
  }
  client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
  client_->set_read_timeout(600);
  const auto session = client_->Get("/api/session");
  if (!session || session->status != 200) throw std::runtime_error("GET /api/session failed");
  token_ = json::parse(session->body).at("csrf_token");
}

httplib::Result Served::post(const std::string& path, const json& body) {
  return answered(client_->Post(path.c_str(), {{"X-CSRF-Token", token_}}, body.dump(), "application/json"), path);
}

httplib::Result Served::upload(const std::string& layer, const std::string& name, const std::string& bytes) {
  const std::string path = "/api/layers/" + layer + "/photos?name=" + percent_encoded(name);
  return answered(client_->Post(path.c_str(), {{"X-CSRF-Token", token_}}, bytes, "application/octet-stream"), path);
}

json Served::get(const std::string& path) {
  const auto r = client_->Get(path.c_str());
  if (!r) throw std::runtime_error("GET " + path + ": " + httplib::to_string(r.error()));
  if (r->status != 200) throw std::runtime_error("GET " + path + ": " + std::to_string(r->status) + " " + r->body);
  return json::parse(r->body);
}

std::string Served::follow(const std::string& job, const std::function<bool(const std::string&)>& until) {
  std::string stream;
  client_->Get(("/api/jobs/" + job + "/events").c_str(), [&](const char* d, std::size_t n) {
    stream.append(d, n);
    return !(until && until(stream));
  });
  return stream;
}

}  // namespace strata::test
