"""How far each train may go: moving block, fixed block, Takagi's laws, speed codes (pure)."""
