#include "latency_proxy.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <list>
#include <mutex>
#include <thread>
#include <vector>

namespace terrain::tools {

using Clock = std::chrono::steady_clock;

bool parse_http_url(const std::string& url, std::string& host, int& port, std::string& path) {
  const std::string scheme = "http://";
  if (url.compare(0, scheme.size(), scheme) != 0) return false;
  const size_t slash = url.find('/', scheme.size());
  const std::string authority = url.substr(scheme.size(), slash == std::string::npos ? std::string::npos : slash - scheme.size());
  path = slash == std::string::npos ? "/" : url.substr(slash);
  const size_t colon = authority.rfind(':');
  host = colon == std::string::npos ? authority : authority.substr(0, colon);
  port = 80;
  if (colon != std::string::npos) {
    try {
      port = std::stoi(authority.substr(colon + 1));
    } catch (...) {
      return false;
    }
  }
  return !host.empty() && port > 0 && port < 65536;
}

namespace {

// One direction of the link: when the bytes offered now finish crossing it.
struct Wire {
  std::mutex mutex;
  Clock::time_point free_at = Clock::now();
  Clock::time_point arrival(size_t bytes, const LinkModel& link) {
    const auto now = Clock::now();
    std::lock_guard<std::mutex> lock(mutex);
    const Clock::time_point start = std::max(now, free_at);
    const double seconds = link.mbit_per_s > 0 ? double(bytes) * 8.0 / (link.mbit_per_s * 1e6) : 0.0;
    free_at = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    return free_at + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(0.5 * link.rtt_ms));
  }
};

void write_all(int fd, const uint8_t* p, size_t n) {
  while (n > 0) {
    const ssize_t w = ::send(fd, p, n, MSG_NOSIGNAL);
    if (w <= 0) return;
    p += w;
    n -= size_t(w);
  }
}

// src -> dst through a wire: a reader stamps each chunk with its arrival, a deliverer writes it then.
struct Pipe {
  int src = -1, dst = -1;
  bool up = false;
  Wire* wire = nullptr;
  LinkModel link;
  std::atomic<uint64_t>* bytes = nullptr;
  std::atomic<uint64_t>* requests = nullptr;
  std::mutex mutex;
  std::condition_variable cv;
  struct Chunk {
    Clock::time_point at;
    std::vector<uint8_t> data;  // empty: end of stream
  };
  std::deque<Chunk> queue;
  bool closed = false;
  std::thread reader, deliverer;

  void start() {
    reader = std::thread([this] { read_loop(); });
    deliverer = std::thread([this] { deliver_loop(); });
  }
  void read_loop() {
    std::vector<uint8_t> buf(64 * 1024);
    uint32_t tail = 0;  // last bytes seen, for "\r\n\r\n" across chunks
    for (;;) {
      const ssize_t n = ::recv(src, buf.data(), buf.size(), 0);
      Chunk c;
      if (n > 0) {
        c.data.assign(buf.begin(), buf.begin() + n);
        bytes->fetch_add(uint64_t(n));
        if (up)
          for (ssize_t i = 0; i < n; ++i) {
            tail = tail << 8 | buf[size_t(i)];
            if (tail == 0x0d0a0d0au) requests->fetch_add(1);
          }
      }
      c.at = wire->arrival(c.data.size(), link);
      {
        std::lock_guard<std::mutex> lock(mutex);
        queue.push_back(std::move(c));
      }
      cv.notify_one();
      if (n <= 0) return;
    }
  }
  void deliver_loop() {
    for (;;) {
      Chunk c;
      {
        std::unique_lock<std::mutex> lock(mutex);
        cv.wait(lock, [&] { return !queue.empty() || closed; });
        if (queue.empty()) return;
        c = std::move(queue.front());
        queue.pop_front();
      }
      std::this_thread::sleep_until(c.at);
      if (c.data.empty()) {
        ::shutdown(dst, SHUT_WR);
        return;
      }
      write_all(dst, c.data.data(), c.data.size());
    }
  }
  void close_and_join() {
    {
      std::lock_guard<std::mutex> lock(mutex);
      closed = true;
    }
    cv.notify_all();
    if (reader.joinable()) reader.join();
    if (deliverer.joinable()) deliverer.join();
  }
};

struct Connection {
  int client = -1, upstream = -1;
  Pipe up, down;
};

}  // namespace

struct LatencyProxy::Impl {
  int listen_fd = -1, port = 0;
  std::string host;
  int upstream_port = 0;
  LinkModel link;
  Wire wire_up, wire_down;
  std::atomic<bool> stopping{false};
  std::thread acceptor;
  std::mutex mutex;
  std::list<Connection> connections;
  std::atomic<uint64_t> accepted{0}, requests{0}, bytes_up{0}, bytes_down{0};

  int connect_upstream() const {
    addrinfo hints{}, *res = nullptr;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    if (::getaddrinfo(host.c_str(), std::to_string(upstream_port).c_str(), &hints, &res) != 0) return -1;
    int fd = -1;
    for (addrinfo* a = res; a && fd < 0; a = a->ai_next) {
      fd = ::socket(a->ai_family, a->ai_socktype, a->ai_protocol);
      if (fd >= 0 && ::connect(fd, a->ai_addr, a->ai_addrlen) != 0) {
        ::close(fd);
        fd = -1;
      }
    }
    ::freeaddrinfo(res);
    return fd;
  }

  void accept_loop() {
    while (!stopping) {
      pollfd p{listen_fd, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const int client = ::accept(listen_fd, nullptr, nullptr);
      if (client < 0) continue;
      const int upstream = connect_upstream();
      if (upstream < 0) {
        ::close(client);
        continue;
      }
      const int one = 1;
      ::setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
      ::setsockopt(upstream, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
      accepted.fetch_add(1);
      std::lock_guard<std::mutex> lock(mutex);
      Connection& c = connections.emplace_back();
      c.client = client;
      c.upstream = upstream;
      c.up.src = client;
      c.up.dst = upstream;
      c.up.up = true;
      c.up.wire = &wire_up;
      c.up.bytes = &bytes_up;
      c.down.src = upstream;
      c.down.dst = client;
      c.down.wire = &wire_down;
      c.down.bytes = &bytes_down;
      for (Pipe* pipe : {&c.up, &c.down}) {
        pipe->link = link;
        pipe->requests = &requests;
        pipe->start();
      }
    }
  }
};

LatencyProxy::LatencyProxy() : impl_(std::make_unique<Impl>()) {}
LatencyProxy::~LatencyProxy() { stop(); }

bool LatencyProxy::start(const std::string& host, int port, LinkModel link, std::string& error) {
  stop();
  impl_ = std::make_unique<Impl>();
  Impl& m = *impl_;
  m.host = host;
  m.upstream_port = port;
  m.link = link;
  m.listen_fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(a);
  if (m.listen_fd < 0 || ::bind(m.listen_fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0 ||
      ::listen(m.listen_fd, 64) != 0 || ::getsockname(m.listen_fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    error = std::string("latency proxy: cannot listen on 127.0.0.1: ") + std::strerror(errno);
    if (m.listen_fd >= 0) ::close(m.listen_fd);
    m.listen_fd = -1;
    return false;
  }
  m.port = ntohs(a.sin_port);
  m.acceptor = std::thread([&m] { m.accept_loop(); });
  return true;
}

void LatencyProxy::stop() {
  if (!impl_ || impl_->listen_fd < 0) return;
  Impl& m = *impl_;
  m.stopping = true;
  if (m.acceptor.joinable()) m.acceptor.join();
  ::close(m.listen_fd);
  m.listen_fd = -1;
  std::lock_guard<std::mutex> lock(m.mutex);
  for (Connection& c : m.connections) {
    ::shutdown(c.client, SHUT_RDWR);
    ::shutdown(c.upstream, SHUT_RDWR);
    c.up.close_and_join();
    c.down.close_and_join();
    ::close(c.client);
    ::close(c.upstream);
  }
  m.connections.clear();
}

int LatencyProxy::port() const { return impl_ ? impl_->port : 0; }

std::string LatencyProxy::proxied(const std::string& url) const {
  std::string host, path;
  int port = 0;
  if (!parse_http_url(url, host, port, path)) return {};
  return "http://127.0.0.1:" + std::to_string(this->port()) + path;
}

ProxyStats LatencyProxy::stats() const {
  if (!impl_) return {};
  return ProxyStats{.connections = impl_->accepted.load(), .requests = impl_->requests.load(),
                    .bytes_up = impl_->bytes_up.load(), .bytes_down = impl_->bytes_down.load()};
}

}  // namespace terrain::tools
