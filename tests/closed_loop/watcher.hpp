// What the closed-loop tests share: a test participant that listens on the cell's topics like
// any outside client, domains and folders of the test's own, and the servo's command line.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "cell_msgsPubSubTypes.h"
#include "closed_loop/process.hpp"
#include "dds/endpoint.hpp"
#include "dds/topics.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "sim/geometry/se3.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

namespace closed_loop {

using namespace std::chrono_literals;
namespace SS = cell_msgs::msg::dds_::ServoStatus_Constants;
namespace SC = cell_msgs::msg::dds_::SimControl_Constants;


inline const std::string kBin = std::string(CELL_BINARY_DIR) + "/bin/";
inline const std::string kSrc = std::string(CELL_SOURCE_DIR);
inline const std::string kPattern = kSrc + "/servo/pattern/data/marray_20x20_k3_w3.txt";
// the pattern the curved objects' scenarios cast (issue 19): their servo must decode it
inline const std::string kCurvedPattern = kSrc + "/servo/pattern/data/marray_20x20_k3_w3_d3.txt";

// A DDS domain no other test of this machine uses while this process lives: ctest runs tests
// in parallel, and two cells on one domain would talk to each other (a pid hash alone once
// collided). The claim is an flock on /tmp/cell_dds_domain_<id>.lock, released when the
// process ends however it ends; the shell tests claim theirs the same way (services.sh).
inline int unique_domain(int salt) {
  const int start = static_cast<int>((getpid() * 7 + salt * 13) % 200);
  for (int i = 0; i < 200; ++i) {
    const int d = 20 + (start + i) % 200;
    const std::string path = "/tmp/cell_dds_domain_" + std::to_string(d) + ".lock";
    const int fd = ::open(path.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return d;  // held (fd kept open) until the process exits
    ::close(fd);
  }
  return 20 + start;
}

// The folders tmp_dir made, removed when every test the program ran passed; a failed run keeps
// them, with the services' logs (a suite's run left some 30 behind in the temporary directory).
struct TmpDirs : ::testing::Environment {
  std::mutex m;
  std::vector<std::string> made;
  void TearDown() override {
    if (!::testing::UnitTest::GetInstance()->Passed()) return;
    std::lock_guard<std::mutex> l(m);
    std::error_code ignored;  // a folder already gone is no error
    for (const std::string& d : made) std::filesystem::remove_all(d, ignored);
  }
};
// registered at namespace scope, as googletest allows: torn down after the last test
inline TmpDirs* const kTmpDirs = static_cast<TmpDirs*>(::testing::AddGlobalTestEnvironment(new TmpDirs));

// A fresh folder of the test's own (mkdtemp). Named by the process id, a folder an earlier run
// left behind came back when the system reused that id: its FIFO made the hostile-loads test
// fail at once (mkfifo: it exists), 1 run of the suite in several.
inline std::string tmp_dir(const std::string& name) {
  std::string d = (std::filesystem::temp_directory_path() / ("dds_loop_" + name + "_XXXXXX")).string();
  if (::mkdtemp(d.data()) == nullptr) throw std::runtime_error("mkdtemp " + d + ": " + std::strerror(errno));
  std::lock_guard<std::mutex> l(kTmpDirs->m);
  kTmpDirs->made.push_back(d);
  return d;
}

// What the test hears on the cell's topics.
struct Watcher {
  explicit Watcher(int domain) {
    cell_dds::ParticipantOptions o;
    o.domain_id = domain;
    o.name = "test_watcher";
    participant = cell_dds::make_participant(o);
    using cell_dds::Stream;
    pose = std::make_unique<cell_dds::Reader<geometry_msgs::msg::dds_::PoseStamped_PubSubType>>(
        *participant, cell_dds::kCameraPoseTopic, cell_dds::reader_qos(Stream::kFrame),
        [this](geometry_msgs::msg::dds_::PoseStamped_&& p) {
          std::lock_guard<std::mutex> l(m);
          last_pose = p;
          ++poses;
          last_pose_time = std::chrono::steady_clock::now();
        });
    status = std::make_unique<cell_dds::Reader<cell_msgs::msg::dds_::ServoStatus_PubSubType>>(
        *participant, cell_dds::kStatusTopic, cell_dds::reader_qos(Stream::kLatched),
        [this](cell_msgs::msg::dds_::ServoStatus_&& s) {
          std::lock_guard<std::mutex> l(m);
          last_status = s;
          if (s.state() == SS::CONVERGED && !converged) converged_at_iteration = s.iteration();
          if (s.state() == SS::CONVERGED) converged = true;
          if (s.state() == SS::LOST) lost = true;
        });
    sim_status = std::make_unique<cell_dds::Reader<cell_msgs::msg::dds_::SimStatus_PubSubType>>(
        *participant, cell_dds::kSimStatusTopic, cell_dds::reader_qos(Stream::kFrame),
        [this](cell_msgs::msg::dds_::SimStatus_&& s) {
          std::lock_guard<std::mutex> l(m);
          for (const auto& r : s.recent_refusals()) refusals.insert(r);
          commands_refused = std::max<long>(commands_refused, s.commands_refused());
          twists_applied = std::max<long>(twists_applied, static_cast<long>(s.twists_applied()));
          twists_rejected = std::max<long>(twists_rejected, static_cast<long>(s.twists_rejected()));
          if (s.state() == cell_msgs::msg::dds_::SimStatus_Constants::ENDED) session_end = s.session_end();
          ++sim_statuses;
        });
    twist = std::make_unique<cell_dds::Reader<geometry_msgs::msg::dds_::TwistStamped_PubSubType>>(
        *participant, cell_dds::kTwistTopic, cell_dds::reader_qos(Stream::kFrame),
        [this](geometry_msgs::msg::dds_::TwistStamped_&& t) {
          std::lock_guard<std::mutex> l(m);
          last_twist = t;
          ++twists;
        });
  }
  Eigen::Isometry3d pose_now() {
    std::lock_guard<std::mutex> l(m);
    return pose_now_unlocked();
  }
  // for predicates of wait_for, which hold the lock
  Eigen::Isometry3d pose_now_unlocked() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    if (!last_pose) return T;
    const auto& p = last_pose->pose();
    T.translation() = Eigen::Vector3d(p.position().x(), p.position().y(), p.position().z());
    T.linear() = Eigen::Quaterniond(p.orientation().w(), p.orientation().x(), p.orientation().y(), p.orientation().z())
                     .toRotationMatrix();
    return T;
  }
  long pose_count() {
    std::lock_guard<std::mutex> l(m);
    return poses;
  }
  // Waits for `n` more camera poses than heard so far (generous bound): "the robot did not
  // move" is checked over frames the cell has stepped, not over a time that a loaded machine
  // may fill with none (issue 20, item 6).
  bool wait_for_poses(long n, std::chrono::milliseconds timeout = std::chrono::milliseconds(240000)) {
    const long from = pose_count();
    return wait_for([&] { return poses >= from + n; }, timeout);
  }
  // True once cellsim's camera pose writer is matched: a run started after that is heard whole,
  // however slow discovery is on a loaded machine (a volatile pose written before the match is
  // never resent).
  bool wait_until_cellsim_heard(std::chrono::milliseconds timeout = std::chrono::milliseconds(60000)) {
    return wait_for([&] { return pose->matched() > 0; }, timeout);
  }
  template <typename Pred>
  bool wait_for(Pred pred, std::chrono::milliseconds timeout) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < until) {
      {
        std::lock_guard<std::mutex> l(m);
        if (pred()) return true;
      }
      std::this_thread::sleep_for(20ms);
    }
    std::lock_guard<std::mutex> l(m);
    return pred();
  }

  std::mutex m;
  std::optional<geometry_msgs::msg::dds_::PoseStamped_> last_pose;
  std::optional<cell_msgs::msg::dds_::ServoStatus_> last_status;
  std::optional<geometry_msgs::msg::dds_::TwistStamped_> last_twist;
  std::chrono::steady_clock::time_point last_pose_time;
  long poses = 0, twists = 0;
  bool converged = false, lost = false;
  // what cellsim says on rt/sim/status: each refusal heard (recent_refusals), the largest counts,
  // and why the session ended (ENDED)
  std::set<std::string> refusals;
  long commands_refused = 0, twists_applied = 0, twists_rejected = 0, sim_statuses = 0;
  std::optional<std::string> session_end;
  bool refused(const std::string& part) const {
    for (const auto& r : refusals)
      if (r.find(part) != std::string::npos) return true;
    return false;
  }
  long converged_at_iteration = -1;  // the iteration of the first CONVERGED heard
  cell_dds::ParticipantPtr participant;
  std::unique_ptr<cell_dds::Reader<geometry_msgs::msg::dds_::PoseStamped_PubSubType>> pose;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::ServoStatus_PubSubType>> status;
  std::unique_ptr<cell_dds::Reader<geometry_msgs::msg::dds_::TwistStamped_PubSubType>> twist;
  std::unique_ptr<cell_dds::Reader<cell_msgs::msg::dds_::SimStatus_PubSubType>> sim_status;
};

// A servo whose CONVERGED status stays the latched one for a minute after cellsim has gone (it
// reports LOST only then): a watcher that matched it late, on a loaded machine, after a run of
// a few seconds, still reads CONVERGED.
inline const std::vector<std::string> kStaysConverged{"--lost-ms", "60000"};

inline std::vector<std::string> servo_args(const std::string& z_hat, const std::vector<std::string>& extra = {},
                                           const std::string& pattern = kPattern) {
  std::vector<std::string> a{kBin + "servo", "run", "--pattern", pattern, "--z-hat", z_hat};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

}  // namespace closed_loop
