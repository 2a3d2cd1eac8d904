r"""Does SUMO's lane-change model move a car into the lane of an ego that ``moveToXY`` places beside it?

The situation of the recording's recurring collision (docs/results/styles.md): at the oval's first stop
line a SUMO-driven car (SUMO's default type, as a reactive replay drives the others) stands in lane 0
beside the ego in lane 1, its front 2 m ahead; a slow car ahead of it in lane 0 gives it a reason to
change lanes; both move off, the car faster (SUMO's driver) than the ego (placed by ``moveToXY`` every
step, 1 m/s^2 up to 5 m/s, as irlsim moves it). Prints every half second the car's and the ego's lane,
position and speed and the ego's gap as the car's left follower (libsumo's ``getLeftFollowers``: negative
while they overlap), and the step the car changes lanes:

    .venv/bin/python studies/style_cut_in.py
"""

from __future__ import annotations

import sys

import libsumo as traci

from irlsim.road import load_road
from irlsim.road.network import sumo_binary


def main() -> int:
    road = load_road(scenario="oval")
    traci.start([sumo_binary("sumo"), "-n", str(road.net_file), "--step-length", "0.1", "--no-step-log"])
    traci.route.add("r", ["A_S1", "S1_X1", "X1_B"])
    traci.vehicle.add("slow", "r", departLane="0", departPos="150", departSpeed="0")
    traci.vehicle.setMaxSpeed("slow", 2.0)
    traci.vehicle.add("car", "r", departLane="0", departPos="120", departSpeed="0")
    traci.vehicle.add("ego", "r", departLane="1", departPos="118", departSpeed="0")
    traci.vehicle.setSpeedMode("ego", 0)
    traci.vehicle.setLaneChangeMode("ego", 0)
    traci.simulationStep()
    x, y = traci.vehicle.getPosition("ego")
    v = 0.0
    for k in range(1, 151):
        v = min(v + 0.1, 5.0)
        x += 0.1 * v
        traci.vehicle.moveToXY("ego", "", -1, x, y, 90.0, keepRoute=2)
        traci.simulationStep()
        lane_car, lane_ego = traci.vehicle.getLaneIndex("car"), traci.vehicle.getLaneIndex("ego")
        gap = dict(traci.vehicle.getLeftFollowers("car")).get("ego")
        if k % 5 == 0 or lane_car == lane_ego:
            print(
                f"t {k / 10:4.1f} s  car: lane {lane_car}, {traci.vehicle.getLanePosition('car'):6.1f} m, "
                f"{traci.vehicle.getSpeed('car'):4.1f} m/s  ego: lane {lane_ego}, "
                f"{traci.vehicle.getLanePosition('ego'):6.1f} m, {traci.vehicle.getSpeed('ego'):4.1f} m/s  "
                f"ego as the car's left follower: " + ("-" if gap is None else f"gap {gap:+.1f} m")
            )
        if lane_car == lane_ego:
            print(f"the car changed into the ego's lane at t = {k / 10:.1f} s")
            break
    traci.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
