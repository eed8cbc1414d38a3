"""Compiled code: CasADi's generated C built and cached at first use, and qpik's own C callers."""
