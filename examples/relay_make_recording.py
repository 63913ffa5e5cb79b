"""Write the SYNTHETIC relay recording shipped in examples/data/relay_sopdt.csv (how it was made, reproducibly).

The "process" is the second-order-plus-dead-time model 2 e^{-s} / ((4 s + 1)(s + 1)) (time in s, deviation
variables without unit), under a biased relay (levels +1.2 / -0.8, so the recording also gives the static gain)
with hysteresis 0.05. The recording is the exact periodic relay orbit of that model
(:func:`dfloop.autotune.cycle.relay_cycle`, closed-form segments; the file starts on the settled oscillation),
sampled every 0.05 s for 12 periods, plus white Gaussian measurement noise of standard deviation 0.02 on y (seed
2026), not fed back to the relay. It is not a measurement of a real plant.

Run: python examples/relay_make_recording.py [PATH]   (default examples/data/relay_sopdt.csv)
"""
import pathlib
import sys

from dfloop.autotune.models import ProcessModel
from dfloop.autotune.record import write_relay_record
from dfloop.autotune.synthetic import synthetic_record

TRUE = ProcessModel(2.0, (4.0, 1.0), 1.0)


def main(argv):
    out = pathlib.Path(argv[0]) if argv else pathlib.Path(__file__).resolve().parent / "data" / "relay_sopdt.csv"
    rec = synthetic_record(TRUE, high=1.2, low=-0.8, hysteresis=0.05, dt=0.05, cycles=12, noise=0.02, seed=2026,
                           meta={"true_model": "K = 2, T1 = 4 s, T2 = 1 s, L = 1 s (SOPDT)",
                                 "made_by": "examples/relay_make_recording.py"})
    write_relay_record(out, rec, digits=8)
    print(f"wrote {out}: {rec!r}")
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
