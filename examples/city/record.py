"""Make examples/city/recording.fcd.xml.gz: SUMO's own traffic on its Ingolstadt game network, recorded.

    python examples/city/record.py [--out examples/city/recording.fcd.xml.gz]

SUMO (the eclipse-sumo wheel's binary) runs the wheel's game scenario fkk_in (its network, its routes,
its drivers: cars, buses, trucks and bicycles, its traffic lights) for 180 s and writes its FCD output,
gzipped: a recording made outside irlsim, as a user's own would be. irlsim reads it as it is.
"""

from __future__ import annotations

import argparse
import subprocess
from pathlib import Path

from irlsim.road.network import sumo_binary, sumo_home

p = argparse.ArgumentParser(description="SUMO's own traffic on its Ingolstadt network, as FCD output")
p.add_argument("--out", default="examples/city/recording.fcd.xml.gz", help="the FCD file written")
args = p.parse_args()

config = Path(sumo_home()) / "tools" / "game" / "fkk_in.sumocfg"
cmd = [sumo_binary("sumo"), "-c", str(config), "--fcd-output", args.out, "--seed", "1"]
subprocess.run(
    [*cmd, "--no-step-log", "true", "--duration-log.disable", "true"], check=True, capture_output=True
)
print(f"wrote {args.out}")
