"""The functional layer of base.roar; OUTCOMES is replaced by the tests that need bad ones."""

from roar_formal.roar.functional import Outcome, Registry

OUTCOMES = {
    "station_pose": [Outcome("bench", True, result={"x": 0.0, "y": 1.5})],
    "load_costmap": [Outcome("loaded", True), Outcome("missing", False)],
    "drive": [Outcome("there", True), Outcome("blocked", False)],
}
SEEN = []   # the costmaps drive was given


class Costmap:
    pass


def registry() -> Registry:
    reg = Registry()
    reg.register("station_pose", lambda k: {"x": float(k), "y": 1.5}, outcomes=OUTCOMES["station_pose"])
    reg.register("load_costmap", Costmap, outcomes=OUTCOMES["load_costmap"])

    def drive(cm, pose):
        SEEN.append(cm)
        return True
    reg.register("drive", drive, outcomes=OUTCOMES["drive"])
    return reg
