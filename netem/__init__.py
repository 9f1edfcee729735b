"""The emulated robot/pilot network (``walkman-netem``): two hosts and the radio between them.

It stands in for the DRC's radio, not for our code, so it lives beside the bridge, not in it.
:mod:`emulation` builds two network namespaces (the robot's and the pilot's PCs), cables each
to a third and runs :mod:`radio_stage` there, which copies every Ethernet frame across as
:mod:`radio_model` times it: serialised at the link's rate, queued, delayed, lost, cut.
"""
