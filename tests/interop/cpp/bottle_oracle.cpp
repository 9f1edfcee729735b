// Differential-testing oracle: real YARP 3.5 Bottle codec behind a line protocol.
//   T <text>   -> "OK <hex of binary> <toString()>"   (parse text, encode)
//   B <hex>    -> "OK <hex of re-encoded> <toString()>" or "ERR"  (decode binary)
// Used by tests/interop/test_bottle_oracle.py to compare yarp_lite with YARP.
#include <yarp/os/Bottle.h>
#include <yarp/os/DummyConnector.h>
#include <yarp/os/Network.h>
#include <iostream>
#include <string>

static std::string toHex(const char* data, size_t len) {
    static const char* digits = "0123456789abcdef";
    std::string out;
    for (size_t i = 0; i < len; i++) {
        unsigned char c = static_cast<unsigned char>(data[i]);
        out += digits[c >> 4];
        out += digits[c & 15];
    }
    return out;
}

static std::string fromHex(const std::string& hex) {
    std::string out;
    for (size_t i = 0; i + 1 < hex.size(); i += 2) {
        out += static_cast<char>(std::stoi(hex.substr(i, 2), nullptr, 16));
    }
    return out;
}

static std::string escapeNewlines(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '\n') { out += "\\x0a"; } else if (c == '\r') { out += "\\x0d"; } else { out += c; }
    }
    return out;
}

int main() {
    yarp::os::Network::setLocalMode(true);
    std::string line;
    while (std::getline(std::cin, line)) {
        if (line.size() < 2) { std::cout << "ERR" << std::endl; continue; }
        yarp::os::Bottle b;
        if (line[0] == 'T') {
            b.fromString(line.substr(2));
        } else {
            std::string raw = fromHex(line.substr(2));
            yarp::os::DummyConnector con;
            con.getWriter().appendBlock(raw.data(), raw.size());
            if (!b.read(con.getReader())) { std::cout << "ERR" << std::endl; continue; }
        }
        size_t len = 0;
        const char* bytes = b.toBinary(&len);
        std::cout << "OK " << toHex(bytes, len) << " " << escapeNewlines(b.toString()) << std::endl;
    }
    return 0;
}
