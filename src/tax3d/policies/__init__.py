"""The policies a rollout runs (`run_episode(env, ..., make_policy=policy)`): each is called as policy(env, state)
after reset, then asked for gripper targets at every step.

    goal.py   GoalPolicy and its Sampling: a goal predictor (TAX3D, or a fixed goal) whose predicted grip vertices
              the grippers follow
    fixed.py  FixedGoal and MeanGoalBaseline: goals that no network predicts (a demo's own, the training set's mean)
    dp3.py    DP3Policy: the DP3 baseline executing its own action windows
    load.py   load_model and load_policy: the one place that tells a TAX3D checkpoint from a DP3 one
"""
