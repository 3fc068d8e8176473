namespace poise::sim {}
