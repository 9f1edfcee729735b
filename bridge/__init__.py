"""The robot/pilot network bridge (paper section 2.6).

Two processes, one per PC, make YARP ports and ROS topics on two name servers
look like one network over a slow link that comes and goes.  Layers, bottom
up: :mod:`wire`/:mod:`compact`/:mod:`state_codec`/:mod:`frames`/
:mod:`datagrams`/:mod:`tiles`/:mod:`fec` (pure codecs), :mod:`link` (the
handshake) and :mod:`frame_session` (acks, resume, events, nudges) and
:mod:`channel_phase` (sans-IO protocol objects), :mod:`journal` (durable
reliable queues), :mod:`tcp_channel`/:mod:`udp_channel` (sockets),
:mod:`endpoints` (YARP ports and ROS topics), :mod:`node` and :mod:`main`
(the ``walkman-bridge`` program).  :mod:`config` reads the XML and
:mod:`flows` decides once how each flow crosses; :mod:`expiry` ages a
command by the time each side held it, :mod:`stop_line` carries the
stop-all.  The emulated robot/pilot network is not part of the bridge: :mod:`netem`.
"""
