"""The field's standard interfaces to the planar world (optional: `pip install -r requirements-interfaces.txt`).

gymnasium_env: a gymnasium.Env for any design, registered as "ModularRobot-v0" on import.
sb3_ppo: Stable-Baselines3 PPO on it, evaluated with the project's metric (docs/interfaces.md).

Nothing here is imported by the stage files: sim2d, gnn and the algorithms never need gymnasium.
"""
