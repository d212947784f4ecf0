"""eval.bench.environment: the machine description a run's timing.json carries."""

import numpy as np

from eval.bench.environment import _cpuinfo, machine_description, machine_label

CPUINFO = """processor\t: 0
model name\t: Intel(R) Xeon(R) Processor
flags\t\t: fpu sse4_2 avx2 avx512f avx512_bf16
processor\t: 1
model name\t: another
flags\t\t: fpu
"""


def test_cpuinfo_takes_the_first_cpu_and_its_isa_widest_first():
    model, isa = _cpuinfo(CPUINFO)
    assert model == "Intel(R) Xeon(R) Processor"
    assert isa == ("avx512_bf16", "avx512f", "avx2", "sse4_2")
    assert _cpuinfo("") == ("", ())


def test_machine_description_names_this_machine():
    env = machine_description()
    assert env["packages"]["numpy"] == np.__version__
    assert env["cpu"] and env["cores"] >= 1 and env["python"].count(".") == 2
    label = machine_label(env)
    assert env["cpu"] in label and f"numpy {np.__version__}" in label
    assert machine_label({}) == "? (-), torch -, numpy -"
