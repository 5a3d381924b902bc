/**
 * @file master_reconnect.h
 * @brief Registers this process's topics and services again after the ROS master restarted.
 *
 * roscpp registers a publisher, subscriber or service with the master once, when it is made; a master that
 * restarts (roscore killed and started again) then knows none of them, and the process is deaf and mute to every
 * node that starts afterwards. rospy nodes re-register; roscpp nodes do not. This watches the master and, when it
 * no longer knows this node, registers every topic and service of the process again through the master's and the
 * node's own XML-RPC APIs (the same calls roscpp makes at start-up), then tells the caller.
 *
 * The checks run on a thread of their own, never on a callback queue: a master on another machine that stops
 * answering can block an XML-RPC call for a while, and frames must not wait for that.
 */
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <ros/ros.h>

namespace kinect_pipeline
{

class MasterReconnect
{
public:
  /**
   * @param services service names (resolved) to register again when this process offers them
   * @param on_reconnect called (from the check's thread) after a re-registration, e.g. to put parameters back
   * @param period how often the master is asked whether it knows this node [s]
   */
  MasterReconnect(std::vector<std::string> services, std::function<void()> on_reconnect, double period = 1.0);
  /** Stops the checks (waits for one in progress). */
  ~MasterReconnect();
  MasterReconnect(const MasterReconnect&) = delete;
  MasterReconnect& operator=(const MasterReconnect&) = delete;

  /** @return how many times the master was found restarted and everything was registered again. */
  std::uint64_t reconnections() const { return reconnections_; }
  /** @return how many registration calls failed (counted, retried at the next check). */
  std::uint64_t failures() const { return failures_; }

private:
  /** Asks the master once and registers again if it does not know this node (only the checking thread). */
  void check();
  bool registerAll(std::string& problem);

  std::vector<std::string> services_;
  std::function<void()> on_reconnect_;
  std::atomic<std::uint64_t> reconnections_{0}, failures_{0};
  bool master_down_ = false;  // only the checking thread touches it
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::thread thread_;  // last: started when everything above exists
};

}  // namespace kinect_pipeline
