"""`step` releases the GIL: Python code runs while a simulation steps, and
two simulations in two Python threads run in parallel on two cores."""

import os
import resource
import threading
import time

import pytest

import projdyn
from conftest import box_tets


def beam():
    # 41 x 9 x 9 = 3,321 vertices: a step takes milliseconds, far more than
    # the Python call around it, so the GIL released matters.
    vertices, tets = box_tets([2.0, 0.4, 0.4], [40, 8, 8])
    model = projdyn.Model()
    b = model.add_body(vertices, tets=tets, density=1000.0)
    model.add_tet_strain(b, stiffness=1.0e6)
    model.fix(b, (vertices[:, 0] <= 1e-3).nonzero()[0])
    return projdyn.Simulation(model, dt=0.01, iterations=10, tolerance=0.0, threads=1)


def test_python_runs_while_a_simulation_steps():
    sim = beam()
    worker = threading.Thread(target=sim.step, args=(30,))
    count = 0
    worker.start()
    while worker.is_alive():
        count += 1
    worker.join()
    assert sim.steps == 30
    # Were the GIL held through the call, this loop could not run until it
    # returned (a handful of turns at most); released, it runs the whole
    # time: over 1e5 turns even at a tenth of a core for the tens of
    # milliseconds the steps take at the least.
    assert count > 1000, count


def cpu_seconds():
    """CPU seconds of this process, all threads."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def machine_busy_seconds():
    """CPU seconds every process of the machine has used (from /proc/stat;
    None where there is none)."""
    try:
        with open("/proc/stat") as f:
            fields = [int(x) for x in f.readline().split()[1:]]
    except OSError:
        return None
    user, nice, system, idle, iowait, irq, softirq, steal = fields[:8]
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def timed(run):
    """Wall seconds of `run` and the cores other processes used meanwhile."""
    busy, own = machine_busy_seconds(), cpu_seconds()
    start = time.perf_counter()
    run()
    wall = time.perf_counter() - start
    others = None
    if busy is not None:
        others = (machine_busy_seconds() - busy - (cpu_seconds() - own)) / wall
    return wall, others


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="needs two cores")
def test_two_threads_run_at_least_one_and_a_half_times_faster_than_serial():
    a, b = beam(), beam()
    steps = 40
    a.step(2)  # warm-up: first-touch allocations
    b.step(2)

    def serial():
        a.step(steps)
        b.step(steps)

    def parallel():
        threads = [threading.Thread(target=s.step, args=(steps,)) for s in (a, b)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()

    # Best of three of each: other processes only ever make a run slower,
    # so the fastest is the least disturbed.
    serial_runs = [timed(serial) for _ in range(3)]
    parallel_runs = [timed(parallel) for _ in range(3)]
    serial_s = min(w for w, _ in serial_runs)
    parallel_s = min(w for w, _ in parallel_runs)
    speedup = serial_s / parallel_s
    others = [o for _, o in serial_runs + parallel_runs if o is not None]
    report = f"serial {serial_s:.3f} s, two threads {parallel_s:.3f} s: {speedup:.2f}x"
    print(report)
    # Other processes taking a quarter of a core or more leave the two
    # threads less than two cores: the speedup is then the machine's load,
    # not the package's, and is not judged.
    if speedup < 1.5 and others and min(others) > 0.25:
        pytest.skip(f"{report}; other processes used {min(others):.2f} cores meanwhile")
    # Two independent simulations on two cores: 2x at best; the contract
    # asks 1.5x, leaving room for memory bandwidth shared by the cores.
    assert speedup >= 1.5, report
