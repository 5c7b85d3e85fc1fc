"""Cook-Torrance Lab: the add-on's modules. Registration lives in register.py."""
