"""Relay auto-tuning from a recording: read the CSV, fit FOPDT and SOPDT models through the exact relay orbit,
tune PI/PID controllers (Ziegler-Nichols, SIMC, AMIGO) and check each closed loop.

The recording examples/data/relay_sopdt.csv is SYNTHETIC (examples/relay_make_recording.py: the exact relay orbit
of 2 e^{-s}/((4s + 1)(s + 1)) plus measurement noise); its true model is in the file's header, so this script can
say how far each estimate is from the truth. With a real recording only the fit's intervals are known.

Run: python examples/relay_autotune.py [CSV] [--figure PATH]   (about 5 s; the figure defaults to
docs/figures/relay_fit.png)
"""
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dfloop.autotune import ProcessModel, closed_loop_check, tune  # noqa: E402
from dfloop.autotune.fit import fit_relay_record  # noqa: E402
from dfloop.autotune.record import load_relay_record  # noqa: E402
from dfloop.plot.autotune import plot_relay_fit  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
TRUE = ProcessModel(2.0, (4.0, 1.0), 1.0)       # the synthetic recording's process (its header says so)


def main(argv):
    figure = HERE.parent / "docs" / "figures" / "relay_fit.png"
    if "--figure" in argv:
        figure = pathlib.Path(argv[argv.index("--figure") + 1])
        argv = argv[:argv.index("--figure")] + argv[argv.index("--figure") + 2:]
    path = pathlib.Path(argv[0]) if argv else HERE / "data" / "relay_sopdt.csv"
    rec = load_relay_record(path)
    print(rec)
    feats = rec.features()
    print(feats)
    Ku, Tu = TRUE.ultimate_point()
    print(f"true ultimate point Ku = {Ku:.5g}, Tu = {Tu:.5g} s; the DF reading is off by "
          f"{100 * (feats.Ku / Ku - 1):+.1f} % and {100 * (feats.Tu / Tu - 1):+.1f} %")
    fits = {kind: fit_relay_record(rec, kind) for kind in ("FOPDT", "SOPDT")}
    for fit in fits.values():
        print(fit)
        print(f"  its Ku, Tu are off the truth by {100 * (fit.Ku / Ku - 1):+.2f} %, {100 * (fit.Tu / Tu - 1):+.2f} %")
    sopdt = fits["SOPDT"]
    tunings = [tune("zn-pi", Ku=feats.Ku, Tu=feats.Tu), tune("zn-pi", Ku=sopdt.Ku, Tu=sopdt.Tu),
               tune("simc-pi", model=sopdt.model), tune("simc-pid", model=sopdt.model),
               tune("amigo-pi", model=sopdt.model), tune("amigo-pid", model=sopdt.model)]
    sources = ["DF reading", "SOPDT fit", "SOPDT fit", "SOPDT fit", "SOPDT fit", "SOPDT fit"]
    print(f"{'rule':<10} {'from':<11} {'Kp':>7} {'Ti [s]':>8} {'Td [s]':>7}   on the true process: {'GM':>5} "
          f"{'PM [deg]':>8} {'Ms':>5} {'overshoot':>9}")
    for src, t in zip(sources, tunings):
        c = closed_loop_check(t.controller, TRUE, t_end=80.0)
        print(f"{t.rule:<10} {src:<11} {t.Kp:7.3f} {t.Ti:8.3f} {t.Td:7.3f}   {'':>19}{c['gain_margin']:5.2f} "
              f"{c['phase_margin']:8.1f} {c['Ms']:5.2f} {100 * c['overshoot']:8.1f} %")
    cplt = plot_relay_fit(sopdt)
    figure.parent.mkdir(parents=True, exist_ok=True)
    cplt.figure.savefig(figure, dpi=110)
    plt.close(cplt.figure)
    print(f"wrote {figure}")
    return fits


if __name__ == "__main__":
    main(sys.argv[1:])
