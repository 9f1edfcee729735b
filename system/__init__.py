"""The whole system: launching both PCs, piloting sessions, comparing topologies, the main job.

* :mod:`processes` -- child processes with collected output (shared with tests and benches);
* :mod:`topology` -- the ``lab`` (one name-server pair) and ``drc`` (two pairs and the
  bridge) topologies, on loopback or emulated hosts, components started in any order;
* :mod:`session` -- a scripted pilot session through the ROS command-line tools, recorded;
* :mod:`compare` -- ``walkman-compare``: the same session in both topologies, the report;
* :mod:`mainjob` -- the README's main job.
"""
