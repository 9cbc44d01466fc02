"""A head as a node on Zenoh: the head service exposed under ``servoface/<site>/<name>/...`` (commands,
AU streams, state, status, presence), synchronised cues across heads, and remote control that is safe
(explicit endpoints, no multicast scouting, credentials, TLS beyond loopback, link loss eases to neutral).

- :mod:`.keys`      the key space
- :mod:`.messages`  the envelope (schema version, sequence number) and validation of every message
- :mod:`.zconfig`   Zenoh configuration: endpoints, scouting off, user/password, TLS
- :mod:`.node`      ``HeadNode``: one head service on one Zenoh session
- :mod:`.client`    controlling heads from elsewhere: list them, stream AUs, send commands, cue them in sync
"""
