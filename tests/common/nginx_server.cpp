#include "nginx_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include "test_data.h"

namespace terrain::test {
namespace {

// A port the kernel calls free now (bound to 127.0.0.1:0, then released).
int free_port() {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return 0;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(a);
  int port = 0;
  if (::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0 &&
      ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &len) == 0)
    port = ntohs(a.sin_port);
  ::close(s);
  return port;
}

bool accepts(int port) {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return false;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = ::connect(s, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
  ::close(s);
  return ok;
}

std::string tail_of(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string s = ss.str();
  return s.size() > 2000 ? s.substr(s.size() - 2000) : s;
}

}  // namespace

std::string nginx_binary() {
  if (::access("/usr/sbin/nginx", X_OK) == 0) return "/usr/sbin/nginx";
  if (const char* path = std::getenv("PATH")) {
    std::stringstream ss(path);
    std::string d;
    while (std::getline(ss, d, ':'))
      if (!d.empty() && ::access((d + "/nginx").c_str(), X_OK) == 0) return d + "/nginx";
  }
  return {};
}

bool make_test_certificate(const std::filesystem::path& dir, std::string& error) {
  std::filesystem::create_directories(dir);
  const std::string cmd = "openssl req -x509 -newkey rsa:2048 -nodes -days 2 -subj /CN=127.0.0.1 -addext "
                          "subjectAltName=IP:127.0.0.1 -keyout '" + (dir / "key.pem").string() + "' -out '" +
                          (dir / "cert.pem").string() + "' > '" + (dir / "openssl.log").string() + "' 2>&1";
  if (std::system(cmd.c_str()) != 0) {
    error = "openssl req -x509 failed: " + tail_of(dir / "openssl.log");
    return false;
  }
  return true;
}

bool NginxServer::start(const std::filesystem::path& dir, std::string& error, const std::filesystem::path& tls_dir) {
  stop();
  const std::string nginx = nginx_binary();
  if (nginx.empty()) {
    error = "nginx is not installed (scripts/setup.sh installs nginx-light)";
    return false;
  }
  dir_ = dir;
  root_ = dir / "www";
  std::filesystem::create_directories(root_ / "slow");
  std::filesystem::create_directories(root_ / "broken");
  std::filesystem::create_directories(dir / "tmp");
  port_ = free_port();
  tls_port_ = tls_dir.empty() ? 0 : free_port();
  if (port_ == 0 || (!tls_dir.empty() && (tls_port_ == 0 || tls_port_ == port_))) {
    error = "no free port on 127.0.0.1";
    return false;
  }
  const std::string d = dir.string(), r = root_.string();
  std::ofstream conf(dir / "nginx.conf");
  conf << "worker_processes 1;\npid " << d << "/nginx.pid;\nevents { worker_connections 256; }\nhttp {\n"
       << "  access_log off;\n  default_type application/octet-stream;\n"
       << "  client_body_temp_path " << d << "/tmp/body;\n  proxy_temp_path " << d << "/tmp/proxy;\n"
       << "  fastcgi_temp_path " << d << "/tmp/fastcgi;\n  uwsgi_temp_path " << d << "/tmp/uwsgi;\n"
       << "  scgi_temp_path " << d << "/tmp/scgi;\n"
       << "  server {\n    listen 127.0.0.1:" << port_ << ";\n";
  if (!tls_dir.empty())
    conf << "    listen 127.0.0.1:" << tls_port_ << " ssl;\n    ssl_certificate " << (tls_dir / "cert.pem").string()
         << ";\n    ssl_certificate_key " << (tls_dir / "key.pem").string() << ";\n";
  conf << "    root " << r << ";\n    location /slow/ { limit_rate 2k; }\n    location /broken/ { return 503; }\n"
       << "  }\n}\n";
  conf.close();
  const std::filesystem::path log = dir / "error.log";
  const pid_t pid = ::fork();
  if (pid < 0) {
    error = "fork failed";
    return false;
  }
  if (pid == 0) {
    std::vector<std::string> args = {nginx, "-p", d, "-c", d + "/nginx.conf", "-e", log.string(), "-g", "daemon off;"};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(nginx.c_str(), argv.data());
    ::_exit(127);
  }
  pid_ = pid;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (std::chrono::steady_clock::now() < until) {
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      error = "nginx exited at start: " + tail_of(log);
      return false;
    }
    if (accepts(port_) && (tls_port_ == 0 || accepts(tls_port_))) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  stop();
  error = "nginx did not accept connections within 10 s: " + tail_of(log);
  return false;
}

void NginxServer::stop() {
  if (pid_ <= 0) return;
  ::kill(pid_, SIGTERM);
  int status = 0;
  ::waitpid(pid_, &status, 0);
  pid_ = -1;
}

std::string NginxServer::url(const std::string& path) const {
  return "http://127.0.0.1:" + std::to_string(port_) + "/" + path;
}

std::string NginxServer::https_url(const std::string& path) const {
  return "https://127.0.0.1:" + std::to_string(tls_port_) + "/" + path;
}

void NginxTest::SetUp() {
  if (nginx_binary().empty()) GTEST_SKIP() << "nginx is not installed (scripts/setup.sh installs nginx-light)";
  dir_ = scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::string error;
  ASSERT_TRUE(server_.start(dir_ / "nginx", error)) << error;
}

}  // namespace terrain::test
