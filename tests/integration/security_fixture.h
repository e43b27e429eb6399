// Shared set-up of the security tests (issue 21): a plant PKI made by the
// deploy script in the scratch folder, and a loopback capture (tcpdump)
// that tells whether some bytes crossed the wire in clear.
#pragma once

#include <signal.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "ambdiag/core/io_util.h"
#include "stream_fixture.h"

namespace ambdiag::testing {

// Runs deploy/security/ambdiag-pki.sh ARGS; true if it exited 0.
inline bool pki(const std::string& args, const fs::path& log) {
  const std::string cmd = std::string(AMBDIAG_PKI_SCRIPT) + " " + args + " >>" + log.string() + " 2>&1";
  return std::system(cmd.c_str()) == 0;
}

// tcpdump on the loopback interface, writing a pcap file; available() is
// false (with why()) where it cannot capture (not installed, no permission).
class LoopbackCapture {
 public:
  LoopbackCapture(const fs::path& dir, const std::string& filter) : pcap_(dir / "capture.pcap"), log_(dir / "tcpdump.log") {
    if (std::system("command -v tcpdump >/dev/null 2>&1") != 0) {
      why_ = "tcpdump is not installed (deploy/install-deps.sh installs it)";
      return;
    }
    // --immediate-mode: packets reach tcpdump at once (not in blocks a
    // second late); -U: written at once; -s 0: whole packets.
    proc_ = std::make_unique<Process>(std::vector<std::string>{"/bin/sh", "-c", "exec tcpdump -i lo -n -s 0 -U --immediate-mode -w " + pcap_.string() + " " + filter},
                                      std::map<std::string, std::string>{}, log_.string());
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (std::chrono::steady_clock::now() < deadline) {
      if (proc_->log().find("listening on") != std::string::npos) {
        available_ = true;
        return;
      }
      if (!proc_->running()) break;
      std::this_thread::sleep_for(20ms);
    }
    why_ = "tcpdump cannot capture on lo: " + proc_->log();
    proc_.reset();
  }
  bool available() const { return available_; }
  const std::string& why() const { return why_; }
  // Stops the capture; the bytes captured (the pcap file).
  std::string stop() {
    if (!proc_) return {};
    std::this_thread::sleep_for(300ms);  // the last packets reach the file
    proc_->signal(SIGINT);
    proc_->wait(5s);
    proc_.reset();
    return fs::exists(pcap_) ? read_file_bytes(pcap_.string()) : std::string();
  }

 private:
  fs::path pcap_, log_;
  std::unique_ptr<Process> proc_;
  std::string why_;
  bool available_ = false;
};

// A streaming test with the plant PKI of its own in the scratch folder.
class PkiTest : public StreamTest {
 protected:
  fs::path pki_dir = dir / "pki";
  fs::path pki_log = dir / "pki.log";
  void SetUp() override { pki_ok("init " + pki_dir.string()); }
  // Runs the deploy script; the test fails (with the script's output) if it does.
  void pki_ok(const std::string& args) { ASSERT_TRUE(pki(args, pki_log)) << read_file_bytes(pki_log.string()); }
};

}  // namespace ambdiag::testing
