"""The kinds of fit, one module each; each declares ``KIND = FitKind(...)`` (rcci.calib.registry).

sensitivity (Table 4.1), kinematics (3.84), gravity (Tables 4.8, 4.9), friction (Tables
4.2-4.4), static (Table 4.6), breakaway (Table 4.5). A new kind is a new module here.
"""
