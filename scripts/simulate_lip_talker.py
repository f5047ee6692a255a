raise NotImplementedError("lip stage pending")
