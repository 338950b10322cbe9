"""gym-pusht (LeRobot's PushT): keypoint demonstrations rebuilt from replay lists, and the keypoint policy
trained on them on a CPU (`keypoint_training`)."""
