// Reference benchmark peer: real YARP 3.5 C++, the numbers yarp_lite is compared with.
//
//   yarp_bench rpc-server NAME                  reply to every request with the request
//   yarp_bench rpc-client TARGET N [REQUEST]    N round trips of a 10-int Bottle (or of
//                                               REQUEST, a Bottle in text: "[get] [encs]");
//                                               prints "rpc median_us p99_us"
//   yarp_bench sink NAME N                      receive N Bottles; prints "sink MB/s"
//   yarp_bench source NAME TARGET N BYTES       send N Bottles holding one BYTES-long blob
#include <yarp/os/Bottle.h>
#include <yarp/os/Network.h>
#include <yarp/os/Port.h>
#include <yarp/os/PortReader.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/ConnectionWriter.h>
#include <yarp/os/RpcClient.h>
#include <yarp/os/RpcServer.h>
#include <yarp/os/Time.h>
#include <yarp/os/Value.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

using namespace yarp::os;

static double now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

class Echo : public PortReader {
public:
    bool read(ConnectionReader& connection) override {
        Bottle request;
        if (!request.read(connection)) { return false; }
        ConnectionWriter* writer = connection.getWriter();
        if (writer != nullptr) { request.write(*writer); }
        return true;
    }
};

class Counter : public PortReader {
public:
    std::mutex lock;
    std::condition_variable done;
    long count = 0, target = 0;
    double first = 0, last = 0;
    size_t bytes = 0;
    bool read(ConnectionReader& connection) override {
        Bottle message;
        if (!message.read(connection)) { return false; }
        std::lock_guard<std::mutex> guard(lock);
        double t = now();
        if (count == 0) { first = t; } else { bytes += message.get(0).asBlobLength(); }
        last = t;
        if (++count >= target) { done.notify_all(); }
        return true;
    }
};

int main(int argc, char** argv) {
    Network yarp;
    if (argc < 3) { std::fprintf(stderr, "usage: see source\n"); return 2; }
    std::string mode = argv[1];
    if (mode == "rpc-server") {
        Echo echo;
        RpcServer server;
        server.setReader(echo);
        if (!server.open(argv[2])) { return 1; }
        std::printf("ready\n");
        std::fflush(stdout);
        while (true) { Time::delay(1.0); }
    }
    if (mode == "rpc-client") {
        RpcClient client;
        if (!client.open("/bench/cpp/client")) { return 1; }
        if (!Network::connect(client.getName(), argv[2])) { return 1; }
        int n = std::atoi(argv[3]);
        Bottle request, reply;
        if (argc > 4) {
            request.fromString(argv[4]);  // e.g. "[get] [encs]" for a control board
        } else {
            for (int i = 0; i < 10; i++) { request.addInt32(i); }
        }
        for (int i = 0; i < 200; i++) { client.write(request, reply); }
        std::vector<double> samples;
        for (int i = 0; i < n; i++) {
            double t = now();
            client.write(request, reply);
            samples.push_back((now() - t) * 1e6);
        }
        std::sort(samples.begin(), samples.end());
        std::printf("rpc %.1f %.1f\n", samples[samples.size() / 2], samples[samples.size() * 99 / 100]);
        return 0;
    }
    if (mode == "sink") {
        Counter counter;
        counter.target = std::atol(argv[3]);
        Port port;
        port.setReader(counter);
        if (!port.open(argv[2])) { return 1; }
        std::printf("ready\n");
        std::fflush(stdout);
        std::unique_lock<std::mutex> guard(counter.lock);
        counter.done.wait(guard, [&] { return counter.count >= counter.target; });
        std::printf("sink %.1f\n", counter.bytes / (counter.last - counter.first) / 1e6);
        return 0;
    }
    if (mode == "source") {
        Port port;
        if (!port.open(argv[2])) { return 1; }
        if (!Network::connect(argv[2], argv[3])) { return 1; }
        long n = std::atol(argv[4]);
        size_t size = std::strtoul(argv[5], nullptr, 10);
        std::string blob(size, '\x5a');
        Bottle message;
        message.add(Value(&blob[0], static_cast<int>(blob.size())));
        for (long i = 0; i < n; i++) { port.write(message); }
        Time::delay(0.5);
        return 0;
    }
    return 2;
}
