"""The runner that flies missions in the simulator, the mission log, plots, reports and benchmarks: the only
package that sees both the world and the pipeline (see README.md in this folder)."""
