// DDS cost of the lockstep loop: VGA rgb8 image out, stamped twist back, as cellsim and the
// servo exchange them, without rendering or decoding. Cross-process (a forked echo process on
// the same loopback/shared-memory transports as the services) against a baseline measured in
// the same run: the same exchange between two participants of one process.
// Prints loop rate (iterations/s) and twist latency (image written -> twist received,
// median and p99).
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "dds/endpoint.hpp"
#include "dds/topics.hpp"
#include "geometry_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"

namespace {

using Clock = std::chrono::steady_clock;
using Image = sensor_msgs::msg::dds_::Image_;
using Twist = geometry_msgs::msg::dds_::TwistStamped_;

// Answers every image with a twist of the same stamp (the servo's part, minus the work).
struct Echo {
  explicit Echo(eprosima::fastdds::dds::DomainParticipant& p)
      : twist(p, "rt/bench/cmd_twist", cell_dds::writer_qos(cell_dds::Stream::kFrame)),
        image(p, "rt/bench/image_raw", cell_dds::reader_qos(cell_dds::Stream::kFrame), [this](Image&& img) {
          Twist t;
          t.header(img.header());
          t.twist().linear().x(0.01);
          twist.write(t);
        }) {}
  cell_dds::Writer<geometry_msgs::msg::dds_::TwistStamped_PubSubType> twist;
  cell_dds::Reader<sensor_msgs::msg::dds_::Image_PubSubType> image;
};

struct Result {
  double rate = 0, median_ms = 0, p99_ms = 0;
};

Result drive(eprosima::fastdds::dds::DomainParticipant& p, int frames) {
  std::mutex m;
  std::condition_variable cv;
  std::optional<std::uint32_t> answered;
  cell_dds::Writer<sensor_msgs::msg::dds_::Image_PubSubType> image(p, "rt/bench/image_raw",
                                                                   cell_dds::writer_qos(cell_dds::Stream::kFrame));
  cell_dds::Reader<geometry_msgs::msg::dds_::TwistStamped_PubSubType> twist(
      p, "rt/bench/cmd_twist", cell_dds::reader_qos(cell_dds::Stream::kFrame), [&](Twist&& t) {
        std::lock_guard<std::mutex> l(m);
        answered = t.header().stamp().nanosec();
        cv.notify_all();
      });
  const auto until = Clock::now() + std::chrono::seconds(30);
  while ((image.matched() == 0 || twist.matched() == 0) && Clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  Image img;
  img.height(480);
  img.width(640);
  img.encoding("rgb8");
  img.step(640 * 3);
  img.data().assign(640 * 480 * 3, 7);
  std::vector<double> latency;
  const auto t0 = Clock::now();
  for (int k = 1; k <= frames; ++k) {
    img.header().stamp().nanosec(static_cast<std::uint32_t>(k));
    img.data()[static_cast<std::size_t>(k) % img.data().size()] ^= 1;
    const auto sent = Clock::now();
    image.write(img);
    std::unique_lock<std::mutex> l(m);
    if (!cv.wait_for(l, std::chrono::seconds(2), [&] { return answered && *answered == static_cast<std::uint32_t>(k); })) {
      std::fprintf(stderr, "dds_loop_bench: frame %d unanswered\n", k);
      break;
    }
    latency.push_back(std::chrono::duration<double, std::milli>(Clock::now() - sent).count());
  }
  const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
  std::sort(latency.begin(), latency.end());
  Result r;
  if (latency.empty()) return r;
  r.rate = static_cast<double>(latency.size()) / secs;
  r.median_ms = latency[latency.size() / 2];
  r.p99_ms = latency[std::min(latency.size() - 1, latency.size() * 99 / 100)];
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::string(argv[1]) == "--echo") {  // the other process
    cell_dds::ParticipantOptions o;
    o.domain_id = std::atoi(argv[2]);
    o.name = "bench_echo_process";
    auto p = cell_dds::make_participant(o);
    Echo echo(*p);
    pause();  // until the parent kills us
    return 0;
  }
  const int frames = argc > 1 ? std::atoi(argv[1]) : 500;
  const int domain = 150 + getpid() % 50;
  // the echo process is started before this one touches DDS (fork after threads is unsafe)
  const std::string domain_arg = std::to_string(domain + 1);
  const pid_t child = fork();
  if (child == 0) {
    execl("/proc/self/exe", argv[0], "--echo", domain_arg.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  Result in_process, cross_process;
  {
    // baseline: both ends in this process (real transports, no fork)
    cell_dds::ParticipantOptions o;
    o.domain_id = domain;
    o.name = "bench_sim";
    auto a = cell_dds::make_participant(o);
    o.name = "bench_echo";
    auto b = cell_dds::make_participant(o);
    Echo echo(*b);
    in_process = drive(*a, frames);
  }
  {
    cell_dds::ParticipantOptions o;
    o.domain_id = domain + 1;
    o.name = "bench_sim_process";
    auto a = cell_dds::make_participant(o);
    cross_process = drive(*a, frames);
  }
  kill(child, SIGKILL);
  waitpid(child, nullptr, 0);
  std::printf("lockstep exchange, VGA rgb8 image -> twist, %d frames\n", frames);
  std::printf("%-44s %12s %12s %12s %12s\n", "benchmark", "iter/s", "median ms", "p99 ms", "vs baseline");
  std::printf("%-44s %12.0f %12.3f %12.3f %11.2fx\n", "dds_loop/baseline_two_participants_one_process", in_process.rate,
              in_process.median_ms, in_process.p99_ms, 1.0);
  std::printf("%-44s %12.0f %12.3f %12.3f %11.2fx\n", "dds_loop/cross_process", cross_process.rate,
              cross_process.median_ms, cross_process.p99_ms,
              in_process.rate > 0 ? cross_process.rate / in_process.rate : 0.0);
  std::printf("(ratio = rate / baseline rate)\n");
  return cross_process.rate > 0 ? 0 : 1;
}
