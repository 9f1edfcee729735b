// A real YARP program on the network clock (run it with YARP_CLOCK=/clock).
//
// It reads commands on standard input, one a line, and answers on standard output:
//   now                 -> "now <Time::now()>"
//   delay S             -> starts Time::delay(S) in a thread; "delayed S" when it returns
//   rpc PORT TEXT...    -> writes the Bottle TEXT to PORT through a yarp::os::RpcClient and
//                          prints "reply <the reply's text>"
//   quit
// The first line it prints is "clock <isSystemClock 0|1> <now>" once YARP's network is up
// (with YARP_CLOCK set, that waits for the clock's first tick, as every YARP program does).
#include <yarp/os/Bottle.h>
#include <yarp/os/Network.h>
#include <yarp/os/RpcClient.h>
#include <yarp/os/Time.h>

#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

int main()
{
    yarp::os::Network network;
    std::printf("clock %d %.9f\n", yarp::os::Time::isSystemClock() ? 1 : 0,
                yarp::os::Time::now());
    std::fflush(stdout);
    std::map<std::string, std::unique_ptr<yarp::os::RpcClient>> clients;
    std::vector<std::thread> delays;
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream words(line);
        std::string verb;
        words >> verb;
        if (verb == "now") {
            std::printf("now %.9f\n", yarp::os::Time::now());
        } else if (verb == "delay") {
            double seconds = 0;
            words >> seconds;
            delays.emplace_back([seconds]() {
                yarp::os::Time::delay(seconds);
                std::printf("delayed %g %.9f\n", seconds, yarp::os::Time::now());
                std::fflush(stdout);
            });
        } else if (verb == "rpc") {
            std::string port;
            words >> port;
            std::string rest;
            std::getline(words, rest);
            auto& client = clients[port];
            if (!client) {
                client = std::make_unique<yarp::os::RpcClient>();
                client->open("...");
                if (!yarp::os::Network::connect(client->getName(), port)) {
                    std::printf("reply <cannot connect to %s>\n", port.c_str());
                    std::fflush(stdout);
                    continue;
                }
            }
            yarp::os::Bottle request;
            yarp::os::Bottle reply;
            request.fromString(rest);
            client->write(request, reply);
            std::printf("reply %s\n", reply.toString().c_str());
        } else if (verb == "quit") {
            break;
        }
        std::fflush(stdout);
    }
    for (auto& client : clients) {
        client.second->close();
    }
    std::_Exit(0);   // a delay still waiting on a stopped clock must not hold the exit
}
