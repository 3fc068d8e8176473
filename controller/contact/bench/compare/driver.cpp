// compare_revisions.sh's program: the sequential method of two source trees (A: old revision,
// B: working tree) timed interleaved, problem by problem, in one process.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

extern "C" {
void* A_make(const char*, int);
int A_count(void*);
double A_time(void*, int, int);
double A_result(void*);
void* B_make(const char*, int);
int B_count(void*);
double B_time(void*, int, int);
double B_result(void*);
}

namespace {
double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * (v.size() - 1) + 0.5)];
}
}  // namespace

int main(int argc, char** argv) {
  const char* recorded = argc > 1 ? argv[1] : "";
  const int passes = argc > 2 ? std::max(1, std::atoi(argv[2])) : 2;
  const int dense = argc > 3 ? std::atoi(argv[3]) : 0;
  void* a = A_make(recorded, 0);
  void* b = B_make(recorded, dense);
  const int n = A_count(a);
  if (n != B_count(b)) {
    std::fprintf(stderr, "the two sides read different corpora\n");
    return 1;
  }
  std::vector<double> ta, tb;
  double max_diff = 0.0;
  for (int pass = 0; pass < passes; ++pass) {
    for (int i = 0; i < n; ++i) {
      if ((i + pass) % 2) {  // alternate which side goes first
        ta.push_back(A_time(a, i, 3));
        tb.push_back(B_time(b, i, 3));
      } else {
        tb.push_back(B_time(b, i, 3));
        ta.push_back(A_time(a, i, 3));
      }
      max_diff = std::max(max_diff, std::abs(A_result(a) - B_result(b)));
    }
  }
  std::printf(
      "double support, %d problems x %d passes, min of 3 each: old median %.3f us p99 %.3f | "
      "new%s median %.3f us p99 %.3f | new/old median %.3f | max answer difference %.2e\n",
      n, passes, percentile(ta, 0.5), percentile(ta, 0.99), dense ? " (dense stages)" : "",
      percentile(tb, 0.5), percentile(tb, 0.99), percentile(tb, 0.5) / percentile(ta, 0.5),
      max_diff);
  return 0;
}
