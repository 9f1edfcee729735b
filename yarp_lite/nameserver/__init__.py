"""The yarp_lite name server: registry, persistent connections, and the server."""
