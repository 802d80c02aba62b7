"""Vector-magnetometer calibration (12 parameters: soft-iron matrix and hard-iron offset)
against the expected Earth field, online by recursive least squares with forgetting."""
