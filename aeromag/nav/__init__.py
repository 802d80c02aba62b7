"""Navigation without GNSS: the 12-state unscented Kalman filter and its sensor models."""
