"""CPU seconds of a cold first geoms-mode monitor step on dm-control's humanoid (issue: first use).

Run it in an empty kernel cache, so that every kernel the step needs is compiled:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/cold_geoms_step.py

Prints the CPU seconds (user + system of this process) of the imports, the fit (from the fit cache when it is
warm), building the monitor and its first ``step()``: the compile happens in the last.
"""
import resource
import time


def cpu():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def main():
    c0, w0 = cpu(), time.perf_counter()
    from dm_control import suite

    from mjccd.mujoco import CCDMonitor, fit_model
    c1 = cpu()
    physics = suite.load("humanoid", "run", task_kwargs={"random": 0}).physics
    model, data = physics.model.ptr, physics.data.ptr
    ellipsoids = fit_model(model)
    c2 = cpu()
    monitor = CCDMonitor(model, data, ellipsoids)
    c3 = cpu()
    monitor.step()
    c4 = cpu()
    print(f"mode {monitor.mode}: imports {c1 - c0:.1f} s CPU, fit {c2 - c1:.1f} s, monitor {c3 - c2:.1f} s, "
          f"first step {c4 - c3:.1f} s; total {c4 - c0:.1f} s CPU, {time.perf_counter() - w0:.1f} s wall")


if __name__ == "__main__":
    main()
