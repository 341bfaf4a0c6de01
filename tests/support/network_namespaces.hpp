#pragma once
// Two network namespaces on this machine joined by a veth pair, each with its own address: what
// a cluster's hosts look like to the processes of one run (one rank per namespace), made and
// removed by the test itself with iproute2 (`ip netns`, `ip link`; root, or CAP_NET_ADMIN and
// CAP_SYS_ADMIN). Where the kernel refuses them, available() is false and why() says so.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace scout::testing {

class NetworkNamespaces {
 public:
  // Names and the subnet 10.213.X.0/24 from the pid, so that concurrent test processes differ.
  NetworkNamespaces() {
    const long id = static_cast<long>(getpid());
    subnet_ = "10.213." + std::to_string(id % 250 + 1);
    for (int i = 0; i < 2; ++i) {
      names_.push_back("scout-" + std::to_string(id) + "-" + std::to_string(i));
      links_.push_back("sv" + std::to_string(id) + (i == 0 ? "a" : "b"));  // at most 15 characters
    }
    if (!run("ip netns add " + names_[0])) {
      why_ = "the kernel refuses network namespaces here (`ip netns add` failed: " + last_error_ + ")";
      return;
    }
    made_ = 1;
    if (!run("ip netns add " + names_[1])) {
      why_ = "a second network namespace was refused (" + last_error_ + ")";
      return;
    }
    made_ = 2;
    // The pair is made in the first namespace and one end moved to the second; each end gets its
    // namespace's address, and both namespaces their loopback (a rank's store connects to itself).
    const bool linked = run("ip -n " + names_[0] + " link add " + links_[0] + " type veth peer name " + links_[1] +
                            " netns " + names_[1]);
    bool configured = linked;
    for (int i = 0; configured && i < 2; ++i) {
      configured = run("ip -n " + names_[i] + " addr add " + address(i) + "/24 dev " + links_[i]) &&
                   run("ip -n " + names_[i] + " link set " + links_[i] + " up") &&
                   run("ip -n " + names_[i] + " link set lo up");
    }
    if (!configured) {
      why_ = "the namespaces' veth link could not be made (" + last_error_ + ")";
      return;
    }
    available_ = true;
  }
  ~NetworkNamespaces() {
    // Removing a namespace removes the veth end inside it, and with it the pair.
    for (int i = made_ - 1; i >= 0; --i) run("ip netns del " + names_[i]);
  }
  NetworkNamespaces(const NetworkNamespaces&) = delete;
  NetworkNamespaces& operator=(const NetworkNamespaces&) = delete;

  bool available() const { return available_; }
  const std::string& why() const { return why_; }
  const std::string& name(int i) const { return names_.at(i); }
  const std::string& link(int i) const { return links_.at(i); }  // namespace i's interface
  std::string address(int i) const { return subnet_ + "." + std::to_string(i + 1); }
  /// The bytes namespace i's interface has sent (-1 if they cannot be read): traffic that crossed
  /// the pair.
  long long sent_bytes(int i) {
    if (!run("ip -n " + names_.at(i) + " -s -o link show dev " + links_.at(i))) return -1;
    // One line: "... link/ether ...\    RX: bytes packets ...\    R1 R2 ...\    TX: bytes ...\    T1 T2 ..."
    const std::size_t tx = last_error_.find("TX:");
    if (tx == std::string::npos) return -1;
    const std::size_t values = last_error_.find('\\', tx);
    return values == std::string::npos ? -1 : std::atoll(last_error_.c_str() + values + 1);
  }
  /// Takes namespace i's end of the pair down (both ends lose their carrier) or up again.
  bool set_link(int i, bool up) {
    return run("ip -n " + names_.at(i) + " link set " + links_.at(i) + (up ? " up" : " down"));
  }

 private:
  bool run(const std::string& command) {
    const std::string full = command + " 2>&1";
    FILE* pipe = popen(full.c_str(), "r");
    if (pipe == nullptr) {
      last_error_ = "popen failed";
      return false;
    }
    std::string output;
    char buffer[256];
    while (std::fgets(buffer, sizeof buffer, pipe)) output += buffer;
    const int status = pclose(pipe);
    while (!output.empty() && (output.back() == '\n' || output.back() == '\r')) output.pop_back();
    last_error_ = output.empty() ? "exit status " + std::to_string(status) : output;
    return status == 0;
  }

  std::string subnet_;
  std::vector<std::string> names_, links_;
  std::string why_, last_error_;
  int made_ = 0;
  bool available_ = false;
};

}  // namespace scout::testing
