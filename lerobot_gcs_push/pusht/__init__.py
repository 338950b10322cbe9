"""gym-pusht (LeRobot's PushT) as a target: px <-> m and its body origin <-> centre of gravity (`frame`), its
env with the state in metres in `info` (`env`), its PD agent's one-action map inverted (`agent`),
lerobot/pusht's features (`dataset`); keypoint demonstrations rebuilt from replay lists, and the keypoint
policy trained on them on a CPU (`keypoint_training`). Nothing is imported here: each module loads alone."""
