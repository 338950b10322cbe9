"""What ships with the package: where the shipped policies and configs are, from any folder or a wheel
(`shipped`), and a LeRobot `pretrained_model` folder in half precision, loadable as it is (`checkpoints`)."""
