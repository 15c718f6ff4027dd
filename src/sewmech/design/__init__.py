"""Design: choosing counterweights, dimensions and tolerances, and sweeping design spaces.

The room for what decides a machine's numbers rather than evaluating them: balancing with
counterweights, sensitivities and tolerance analysis, optimisation of dimensions, sweeps over
many designs. It builds on the engine and the sewing analyses; the applications use it.
"""
