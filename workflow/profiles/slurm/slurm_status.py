#!/usr/bin/env python3
"""Snakemake cluster-status command for Slurm: prints success, running or failed for a job id.

`scontrol show job -o ID` is asked first (it knows a job until MinJobAge, 300 s by default,
after its end, and needs no accounting), then `sacct` (which knows ended jobs where accounting
is on). COMPLETED -> success; pending, running, requeued, suspended and other transient states,
or no answer at all (the controller busy or restarting, the job already forgotten without
accounting) -> running; any other end (FAILED, CANCELLED, TIMEOUT, OUT_OF_MEMORY, NODE_FAIL,
PREEMPTED, BOOT_FAIL, DEADLINE) -> failed. Node failures are retried by Slurm (the profile
submits with --requeue): such a job is pending again, hence running.
"""
import re
import subprocess
import sys

FAILED = {"FAILED", "CANCELLED", "TIMEOUT", "OUT_OF_MEMORY", "NODE_FAIL", "PREEMPTED",
          "BOOT_FAIL", "DEADLINE", "REVOKED", "SPECIAL_EXIT"}


def ask(cmd):
    """The command's output; "" when it fails or takes over 15 s (an unreachable controller:
    scontrol retries for a while), which reads as no answer, i.e. running."""
    try:
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                           timeout=15, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return ""
    return r.stdout.decode("utf-8", "replace") if r.returncode == 0 else ""


def state(jobid):
    m = re.search(r"\bJobState=(\S+)", ask(["scontrol", "show", "job", "-o", jobid]))
    if m:
        return m.group(1)
    for line in ask(["sacct", "-X", "-n", "-P", "-o", "State", "-j", jobid]).splitlines():
        if line.strip():
            return line.split()[0]  # "CANCELLED by 0" -> CANCELLED
    return ""


def main():
    jobid = sys.argv[1].split(";")[0]  # sbatch --parsable: "ID" or "ID;CLUSTER"
    s = state(jobid).rstrip("+")
    if s == "COMPLETED":
        print("success")
    elif s in FAILED:
        print("failed")
    else:
        print("running")


if __name__ == "__main__":
    main()
