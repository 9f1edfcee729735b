"""Finding the name server the way YARP does."""

from yarp_lite.nameconfig import (ServerAddress, config_file, namespace, parse_config,
                                  read_server_address, set_namespace, write_server_address)


def test_config_locations(tmp_path):
    env = {"YARP_CONFIG_HOME": str(tmp_path)}
    assert config_file("/root", env) == tmp_path / "yarp.conf"
    assert config_file("/robot/a", env) == tmp_path / "_robot_a.conf"
    assert config_file("/root", {"XDG_CONFIG_HOME": "/x"}) == \
        __import__("pathlib").Path("/x/yarp/yarp.conf")


def test_namespace_from_env_then_file(tmp_path):
    env = {"YARP_CONFIG_HOME": str(tmp_path)}
    assert namespace(env) == "/root"
    set_namespace("/pilot", env)
    assert namespace(env) == "/pilot"
    assert namespace({**env, "YARP_NAMESPACE": "/robot /other"}) == "/robot"


def test_round_trip_and_formats(tmp_path):
    env = {"YARP_CONFIG_HOME": str(tmp_path)}
    write_server_address(ServerAddress("10.0.0.2", 10000), "/root", env)
    assert (tmp_path / "yarp.conf").read_text() == "10.0.0.2 10000 yarp\n"
    assert read_server_address("/root", env) == ServerAddress("10.0.0.2", 10000)
    assert parse_config("[name]\nhost 1.2.3.4\nport 55\n") == ServerAddress("1.2.3.4", 55)
    assert parse_config("") is None and parse_config("garbage") is None
