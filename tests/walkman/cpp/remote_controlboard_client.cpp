// A real YARP client of a control board: opens remote_controlboard on REMOTE and
// drives joint AXIS the way yarpmotorgui or an iCub module would.
//   remote_controlboard_client REMOTE LOCAL CARRIER AXIS TARGET_DEG
// Prints one line per step ("axes 2", "name 0 NeckYawj", "encoder 0 1.5", ...) and
// "reached <mode> <deg>" when the encoder got within 1 degree of the target in
// position mode (IPositionControl::positionMove), "motion done 1" once checkMotionDone
// says the trajectory finished, and then in position-direct mode
// (IPositionDirect::setPosition); exits 1 with a reason otherwise.
#include <yarp/os/Network.h>
#include <yarp/os/Property.h>
#include <yarp/os/Time.h>
#include <yarp/dev/PolyDriver.h>
#include <yarp/dev/IAxisInfo.h>
#include <yarp/dev/IControlMode.h>
#include <yarp/dev/IEncodersTimed.h>
#include <yarp/dev/IPositionControl.h>
#include <yarp/dev/IPositionDirect.h>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace yarp::dev;

static bool reach(IEncodersTimed* enc, int axis, double target, const char* mode) {
    double value = NAN, stamp = 0;
    for (int i = 0; i < 400; i++) {  // 20 s
        if (enc->getEncoderTimed(axis, &value, &stamp) && std::fabs(value - target) < 1.0) {
            std::printf("reached %s %.3f stamp %.3f\n", mode, value, stamp);
            std::fflush(stdout);
            return true;
        }
        yarp::os::Time::delay(0.05);
    }
    std::printf("not reached %s: encoder %.3f, target %.3f\n", mode, value, target);
    return false;
}

int main(int argc, char** argv) {
    if (argc != 6) {
        std::fprintf(stderr, "usage: %s REMOTE LOCAL CARRIER AXIS TARGET_DEG\n", argv[0]);
        return 2;
    }
    yarp::os::Network yarp;
    yarp::os::Property options;
    options.put("device", "remote_controlboard");
    options.put("remote", argv[1]);
    options.put("local", argv[2]);
    options.put("carrier", argv[3]);
    const int axis = std::atoi(argv[4]);
    const double target = std::atof(argv[5]);
    PolyDriver driver(options);
    if (!driver.isValid()) {
        std::printf("could not open remote_controlboard on %s\n", argv[1]);
        return 1;
    }
    IPositionControl* pos = nullptr;
    IPositionDirect* direct = nullptr;
    IEncodersTimed* enc = nullptr;
    IControlMode* modes = nullptr;
    IAxisInfo* info = nullptr;
    if (!driver.view(pos) || !driver.view(direct) || !driver.view(enc) || !driver.view(modes)
        || !driver.view(info)) {
        std::printf("missing interfaces\n");
        return 1;
    }
    int axes = 0;
    pos->getAxes(&axes);
    std::printf("axes %d\n", axes);
    for (int j = 0; j < axes; j++) {
        std::string name;
        info->getAxisName(j, name);
        std::printf("name %d %s\n", j, name.c_str());
    }
    std::vector<double> encs(axes, NAN), stamps(axes, 0);
    bool seen = false;
    for (int i = 0; i < 100 && !seen; i++) {  // the first stateExt:o may take a moment
        seen = enc->getEncodersTimed(encs.data(), stamps.data());
        if (!seen) yarp::os::Time::delay(0.05);
    }
    if (!seen) {
        std::printf("no encoders from %s/stateExt:o\n", argv[1]);
        return 1;
    }
    for (int j = 0; j < axes; j++) std::printf("encoder %d %.3f\n", j, encs[j]);
    std::fflush(stdout);

    modes->setControlMode(axis, VOCAB_CM_POSITION);
    pos->setRefSpeed(axis, 40.0);
    pos->positionMove(axis, target);
    if (!reach(enc, axis, target, "position")) return 1;
    // The encoder comes within a degree while the trajectory may still be finishing: poll
    // checkMotionDone the way iCub modules do (yarp::dev::IPositionControl's idiom).
    bool done = false;
    for (int i = 0; i < 100 && !done; i++) {  // 5 s
        pos->checkMotionDone(axis, &done);
        if (!done) yarp::os::Time::delay(0.05);
    }
    std::printf("motion done %d\n", done ? 1 : 0);

    modes->setControlMode(axis, VOCAB_CM_POSITION_DIRECT);
    int mode = 0;
    modes->getControlMode(axis, &mode);
    std::printf("mode %s\n", yarp::os::Vocab32::decode(mode).c_str());
    const double back = target / 2;
    for (int i = 0; i < 200; i++) {  // stream, as a 100 Hz controller would
        direct->setPosition(axis, back);
        yarp::os::Time::delay(0.01);
    }
    if (!reach(enc, axis, back, "direct")) return 1;
    driver.close();
    return 0;
}
