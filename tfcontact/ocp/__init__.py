"""tfcontact.ocp"""
