"""Write examples/scope_chain1_wall.csv: a wall-sensor record of chain 1 made from the model.

The record is what a Tektronix TDS2024B saves to its USB stick ("spreadsheet" CSV: 18 setting
lines in the first two columns, time and volts in the 4th and 5th), of the wall force of
examples/lab_chain1.toml with hidden parameters that `hertzchain fit` should recover:

- striker speed 0.25 m/s (the config's first guess is 0.2 m/s);
- a PCB 208A11 sensor whose real sensitivity is 109.0 mV/N, 0.970 of the nominal 112.40 mV/N
  (so the fitted gain is 0.970 when the file is read with --sensor pcb_208a11);
- 5 mV rms noise, an 8-bit 2 V window, 2500 points at 2.5 MS/s, a random sample-clock phase,
  triggered at 0.5 N on the signal itself with 20 % pretrigger;
- a 20 mV DC offset.

Run from the repository root: ``.venv/bin/python examples/make_scope_example.py``.
"""

from __future__ import annotations

from pathlib import Path

import hertzchain as hc
from hertzchain.config import build_model, build_probes, load_config
from hertzchain.fileio import write_text
from hertzchain.instrument import Instrument

HERE = Path(__file__).resolve().parent
VELOCITY, SENSITIVITY, OFFSET_V = 0.25, 109.0, 0.020


def main() -> None:
    cfg = load_config(HERE / "lab_chain1.toml", [f"striker.velocity={VELOCITY}"])
    ds = hc.simulate(build_model(cfg), cfg.run.duration, build_probes(cfg))
    scope = Instrument(sensitivity_mV_per_N=SENSITIVITY, noise_rms_mV=5.0, sample_rate=2.5e6, record_length=2500,
                       trigger_level_N=0.5, pretrigger_fraction=0.2, bits=8, full_scale_V=2.0, offset_V=0.6,
                       n_average=1, trigger_jitter=True, seed=2006)
    acq = scope.acquire(ds.time.values, ds.wall_force.values)
    t, volts = acq.time, acq.volts + OFFSET_V
    settings = [("Record Length", f"{t.size:.6e}"), ("Sample Interval", f"{t[1] - t[0]:.6e}"),
                ("Trigger Point", f"{acq.trigger_index:.12e}"), ("", ""), ("", ""), ("", ""),
                ("Source", "CH1"), ("Vertical Units", "V"), ("Vertical Scale", "2.500000e-01"),
                ("Vertical Offset", "-6.000000e-01"), ("Horizontal Units", "s"), ("Horizontal Scale", "1.000000e-04"),
                ("Pt Fmt", "Y"), ("Yzero", "0.000000e+00"), ("Probe Atten", "1.000000e+00"),
                ("Model Number", "TDS2024B"), ("Serial Number", "C010101"), ("Firmware Version", "FV:v22.16")]
    lines = [f"{name},{value},,{ti:.12f},{vi:.5f}," for (name, value), ti, vi in
             zip(settings + [("", "")] * (t.size - len(settings)), t, volts)]
    write_text(HERE / "scope_chain1_wall.csv", "\r\n".join(lines) + "\r\n")
    print(f"wrote {HERE / 'scope_chain1_wall.csv'}: trigger at {acq.trigger_time * 1e3:.6f} ms + clock phase "
          f"{acq.jitter[0] * 1e9:.1f} ns on the simulation clock (the true time_offset "
          f"{(acq.trigger_time + acq.jitter[0]) * 1e3:.6f} ms)")


if __name__ == "__main__":
    main()
