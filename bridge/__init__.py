"""The robot/pilot network bridge (paper section 2.6).

Two processes, one per PC, make YARP ports and ROS topics on two name servers look like one
network over a slow link that comes and goes.  Bottom up:

* :mod:`bridge.wire` -- pure codecs (varints, compact Bottles, the robot state, frames,
  datagrams, tiles, FEC) and the keyed handshake;
* :mod:`bridge.transport` -- the journal and the TCP and UDP channels that carry the bytes;
* :mod:`bridge.gym` -- what the link owes a GYM module: delivery and receipts, expiry, status
  events, the stop-all, the stand-ins;
* here: :mod:`config` reads the XML and :mod:`flows` decides once how each flow crosses;
  :mod:`core` decides what each message does (sans-IO: events in, actions out); :mod:`node`
  performs it, with the :mod:`endpoints` (YARP ports and ROS topics); :mod:`main` is the
  ``walkman-bridge`` program.

The emulated robot/pilot network is not part of the bridge: :mod:`netem`.
"""
