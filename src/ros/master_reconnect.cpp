#include "kinect_pipeline/ros/master_reconnect.h"

#include <chrono>
#include <mutex>
#include <thread>
#include <utility>

#include <boost/make_shared.hpp>

#include <ros/connection_manager.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/service_manager.h>
#include <ros/this_node.h>
#include <ros/xmlrpc_manager.h>
#include <xmlrpcpp/XmlRpc.h>

namespace kinect_pipeline
{

namespace
{
/**
 * One call of this process's own XML-RPC (slave) API, driven by roscpp's XML-RPC thread as roscpp's own pending
 * connections are. A blocking XmlRpcClient::execute waited for ever when ros::shutdown stopped that server during
 * the call, and the destructor's join with it: a node that did not exit on SIGINT (seen once in a test's teardown).
 */
class SelfCall : public ros::ASyncXMLRPCConnection
{
public:
  SelfCall(const std::string& host, int port) : client_(host.c_str(), port, "/") {}
  bool start(const std::string& method, const XmlRpc::XmlRpcValue& params)
  {
    return client_.executeNonBlock(method.c_str(), params);
  }
  void addToDispatch(XmlRpc::XmlRpcDispatch* d) override
  {
    d->addSource(&client_, XmlRpc::XmlRpcDispatch::WritableEvent | XmlRpc::XmlRpcDispatch::Exception);
  }
  void removeFromDispatch(XmlRpc::XmlRpcDispatch* d) override { d->removeSource(&client_); }
  bool check() override  // roscpp's XML-RPC thread
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!done_ && client_.executeCheckDone(result_))
    {
      done_ = true;
      fault_ = client_.isFault();
    }
    return done_;
  }
  /** @return whether the answer came (and was no fault), with it in @p result. */
  bool answered(XmlRpc::XmlRpcValue& result)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (done_ && !fault_)
      result = result_;
    return done_ && !fault_;
  }
  bool done()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return done_;
  }

private:
  XmlRpc::XmlRpcClient client_;
  std::mutex mutex_;
  XmlRpc::XmlRpcValue result_;
  bool done_ = false, fault_ = false;
};

/** Calls a method of this process's own XML-RPC API, waiting 2 s at most and not past ros::shutdown; @return its
 *  value (the third element). */
bool callSelf(const std::string& method, XmlRpc::XmlRpcValue& params, XmlRpc::XmlRpcValue& value)
{
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(ros::XMLRPCManager::instance()->getServerURI(), host, port))
    return false;
  const auto call = boost::make_shared<SelfCall>(host, static_cast<int>(port));
  if (!call->start(method, params))
    return false;
  ros::XMLRPCManager::instance()->addASyncConnection(call);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (!call->done() && ros::ok() && !ros::isShuttingDown() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));  // the answer comes on roscpp's thread
  ros::XMLRPCManager::instance()->removeASyncConnection(call);
  XmlRpc::XmlRpcValue result;
  if (!call->answered(result) || result.getType() != XmlRpc::XmlRpcValue::TypeArray || result.size() != 3 ||
      int(result[0]) != 1)
    return false;
  value = result[2];
  return true;
}

/** [[topic, type], ...] of this node's publications or subscriptions, from its own slave API. */
bool topicList(const std::string& method, XmlRpc::XmlRpcValue& list)
{
  XmlRpc::XmlRpcValue params;
  params[0] = ros::this_node::getName();
  return callSelf(method, params, list) && list.getType() == XmlRpc::XmlRpcValue::TypeArray;
}
}  // namespace

MasterReconnect::MasterReconnect(std::vector<std::string> services, std::function<void()> on_reconnect, double period)
  : services_(std::move(services)), on_reconnect_(std::move(on_reconnect))
{
  const auto wait = std::chrono::duration<double>(period);
  thread_ = std::thread([this, wait] {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!wake_.wait_for(lock, wait, [this] { return stop_; }))
    {
      lock.unlock();
      if (ros::ok())
        check();
      lock.lock();
    }
  });
}

MasterReconnect::~MasterReconnect()
{
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void MasterReconnect::check()
{
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  request[1] = ros::this_node::getName();
  if (ros::master::execute("lookupNode", request, response, payload, false))
  {
    if (master_down_)
      ROS_INFO("%s: the ROS master is back and still knows this node", ros::this_node::getName().c_str());
    master_down_ = false;
    return;  // the master knows this node: nothing to do
  }
  if (!ros::master::check())
  {
    if (!master_down_)
      ROS_WARN("%s: the ROS master at %s does not answer; serving the connections there are and registering "
               "again when it is back",
               ros::this_node::getName().c_str(), ros::master::getURI().c_str());
    master_down_ = true;
    return;
  }
  // The master answers but does not know this node: it was restarted, or this node is shutting down (roscpp has
  // unregistered its topics), when nothing is to be registered.
  if (!ros::ok() || ros::isShuttingDown())
    return;
  std::string problem;
  if (registerAll(problem))
  {
    ++reconnections_;
    master_down_ = false;
    ROS_WARN("%s: the ROS master at %s was restarted; registered this process's topics and services again",
             ros::this_node::getName().c_str(), ros::master::getURI().c_str());
    if (on_reconnect_)
      on_reconnect_();
  }
  else
  {
    ++failures_;
    ROS_ERROR_THROTTLE(10.0, "%s: registering again with the restarted master failed (%s); retrying",
                       ros::this_node::getName().c_str(), problem.c_str());
  }
}

bool MasterReconnect::registerAll(std::string& problem)
{
  const std::string me = ros::this_node::getName();
  const std::string api = ros::XMLRPCManager::instance()->getServerURI();
  XmlRpc::XmlRpcValue pubs, subs;
  if (!topicList("getPublications", pubs) || !topicList("getSubscriptions", subs))
  {
    problem = "this node's own XML-RPC API did not list its topics";
    return false;
  }
  bool ok = true;
  for (int i = 0; i < pubs.size(); ++i)
  {
    XmlRpc::XmlRpcValue request, response, payload;
    request[0] = me;
    request[1] = pubs[i][0];
    request[2] = pubs[i][1];
    request[3] = api;
    if (!ros::master::execute("registerPublisher", request, response, payload, false))
    {
      problem = "registerPublisher " + std::string(pubs[i][0]);
      ok = false;
    }
  }
  for (int i = 0; i < subs.size(); ++i)
  {
    XmlRpc::XmlRpcValue request, response, publishers;
    request[0] = me;
    request[1] = subs[i][0];
    request[2] = subs[i][1];
    request[3] = api;
    if (!ros::master::execute("registerSubscriber", request, response, publishers, false))
    {
      problem = "registerSubscriber " + std::string(subs[i][0]);
      ok = false;
      continue;
    }
    // What the master would have sent as publisherUpdate: connect to the publishers there already are.
    XmlRpc::XmlRpcValue update, ignored;
    update[0] = std::string("/master");
    update[1] = subs[i][0];
    update[2] = publishers;
    if (!callSelf("publisherUpdate", update, ignored))
    {
      problem = "publisherUpdate " + std::string(subs[i][0]);
      ok = false;
    }
  }
  const std::string service_api =
      "rosrpc://" + ros::network::getHost() + ":" + std::to_string(ros::ConnectionManager::instance()->getTCPPort());
  for (const std::string& name : services_)
  {
    if (!ros::ServiceManager::instance()->lookupServicePublication(name))
      continue;
    XmlRpc::XmlRpcValue request, response, payload;
    request[0] = me;
    request[1] = name;
    request[2] = service_api;
    request[3] = api;
    if (!ros::master::execute("registerService", request, response, payload, false))
    {
      problem = "registerService " + name;
      ok = false;
    }
  }
  return ok;
}

}  // namespace kinect_pipeline
