// A TCP proxy on 127.0.0.1 that makes a local server look distant: each direction's bytes arrive
// rtt/2 after they were sent and no faster than the link's bandwidth (one link per direction,
// shared by every connection, as a real access link is). For the benchmarks (and tests) of reading
// archives over HTTP from a server on this machine. Threads: one to accept, two per connection
// and direction (read, deliver).
#pragma once
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

namespace terrain::tools {

struct LinkModel {
  double rtt_ms = 0;      // round trip added: rtt/2 each way
  double mbit_per_s = 0;  // bandwidth of each direction; 0: unlimited
};

struct ProxyStats {
  uint64_t connections = 0;  // accepted
  uint64_t requests = 0;     // HTTP requests seen going up (header ends, "\r\n\r\n")
  uint64_t bytes_up = 0, bytes_down = 0;
};

class LatencyProxy {
 public:
  LatencyProxy();
  ~LatencyProxy();
  LatencyProxy(const LatencyProxy&) = delete;
  LatencyProxy& operator=(const LatencyProxy&) = delete;

  // Listens on a free 127.0.0.1 port and forwards each connection to host:port through `link`.
  // False with a message when it cannot listen.
  bool start(const std::string& host, int port, LinkModel link, std::string& error);
  // Closes every connection and joins the threads (idempotent).
  void stop();
  int port() const;
  // `url` (http://host:port/path of the upstream) with the proxy's address instead; "" when `url`
  // is not an http:// URL.
  std::string proxied(const std::string& url) const;
  ProxyStats stats() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Host and port of an http:// URL (port 80 by default); false for anything else.
bool parse_http_url(const std::string& url, std::string& host, int& port, std::string& path);

}  // namespace terrain::tools
