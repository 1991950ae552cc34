// A real web server for the tests that read archives over HTTP: nginx started by the test on a free
// 127.0.0.1 port, with its configuration, logs and pid in a scratch folder of the build tree (no
// systemd, nothing outside the build tree), waited for until it accepts connections, stopped by the
// destructor. It serves `root()`; /slow/ is throttled (limit_rate) and /broken/ answers 503, for
// the fault tests. With a certificate (make_test_certificate) it serves https on a second port.
#pragma once
#include <gtest/gtest.h>
#include <sys/types.h>

#include <filesystem>
#include <string>

namespace terrain::test {

// Where nginx is: /usr/sbin/nginx or on PATH; empty when not installed.
std::string nginx_binary();

// A self-signed certificate for 127.0.0.1 (openssl req -x509) as cert.pem + key.pem in `dir`;
// false (with a message) when openssl fails or is absent.
bool make_test_certificate(const std::filesystem::path& dir, std::string& error);

class NginxServer {
 public:
  NginxServer() = default;
  ~NginxServer() { stop(); }
  NginxServer(const NginxServer&) = delete;
  NginxServer& operator=(const NginxServer&) = delete;

  // Starts nginx on free ports with its files under `dir` (created); with `tls_dir` (holding
  // cert.pem and key.pem) also https. False with a message (error.log's tail) on failure.
  bool start(const std::filesystem::path& dir, std::string& error, const std::filesystem::path& tls_dir = {});
  // Stops the server and waits for it (idempotent).
  void stop();
  bool running() const { return pid_ > 0; }

  const std::filesystem::path& root() const { return root_; }  // the folder it serves
  std::string url(const std::string& path) const;              // http://127.0.0.1:PORT/path
  std::string https_url(const std::string& path) const;        // https://127.0.0.1:PORT2/path

 private:
  pid_t pid_ = -1;
  int port_ = 0, tls_port_ = 0;
  std::filesystem::path dir_, root_;
};

// A fixture whose every test has its own scratch folder (dir_, named after the test) and a running
// server (server_, its files under dir_/nginx). Where nginx is not installed the test is skipped,
// naming the package. A derived SetUp() calls this one first and returns when IsSkipped() or
// HasFatalFailure().
class NginxTest : public ::testing::Test {
 protected:
  void SetUp() override;
  std::filesystem::path dir_;
  NginxServer server_;
};

}  // namespace terrain::test
