"""Shared test configuration: one torch thread per test process keeps tiny-network tests fast and stable."""

import torch as th

th.set_num_threads(1)
