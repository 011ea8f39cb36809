/* A prefetch hint for the event-driven neighbour search (terrace_event_driven). */
void terrace_prefetch(const double *x) { __builtin_prefetch(x); __builtin_prefetch(x + 7); }
