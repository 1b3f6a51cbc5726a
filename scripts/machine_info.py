"""The machine a timing ran on, as the timing scripts (time_runs.py, bench_ab.py) record it:
the CPU model /proc/cpuinfo gives and the 1-minute load average. Standard library only."""
import os


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def load_average():
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")
