"""MAVLink in one place: mission items and their messages, mission files, the link.

``items`` builds a plan's mission and converts its rows to and from MAVLink messages;
``files`` reads and writes ``.waypoints`` and ``.plan`` files; ``link`` speaks the mission
protocol, ``upload`` puts a file on a vehicle, ``telemetry`` runs the node's vehicle link.
Imports the rest of the vehicle side, never the reverse.
"""
