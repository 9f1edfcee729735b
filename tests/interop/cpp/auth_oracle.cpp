// What real YARP 3.5's AuthHMAC constructor finds: the auth.conf the
// ResourceFinder singleton locates (from this process's environment and
// current directory) and the [AUTH] key read from it, as AuthHMAC.cpp does.
// Prints "path <file or nothing>", then "group 0|1" and "key <hex>" when a
// file was found.  tests/interop/test_auth_interop.py compares yarp_lite.auth.
#include <yarp/os/Bottle.h>
#include <yarp/os/Property.h>
#include <yarp/os/ResourceFinder.h>
#include <yarp/os/ResourceFinderOptions.h>

#include <cstdio>
#include <string>

int main()
{
    yarp::os::ResourceFinder& rf = yarp::os::ResourceFinder::getResourceFinderSingleton();
    yarp::os::ResourceFinderOptions options;
    options.messageFilter = yarp::os::ResourceFinderOptions::ShowNone;
    std::string fname = rf.findFile("auth.conf", options);
    std::printf("path %s\n", fname.c_str());
    if (fname.empty()) {
        return 0;
    }
    yarp::os::Property config;
    config.fromConfigFile(fname);
    yarp::os::Bottle group = config.findGroup("AUTH");
    std::printf("group %d\n", group.isNull() ? 0 : 1);
    std::string key = group.find("key").asString();
    std::printf("key ");
    for (unsigned char ch : key) {
        std::printf("%02x", ch);
    }
    std::printf("\n");
    return 0;
}
