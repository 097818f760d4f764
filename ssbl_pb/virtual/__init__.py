"""The simulated robot behind deploy's ``Robot`` interface (robot: ``SimRobot``, ``SimClock``) and the virtual
Pepper that serves it over NAOqi's qi protocol (pepper; ``python -m ssbl_pb.virtual``)."""
