// Not built: the reproducer for why SWEPTCCD_SANITIZE turns off GCC's vptr
// check (CMakeLists.txt). With Debian 12's g++ 12.2,
//   g++ -std=c++17 -O0 -fsanitize=vptr gcc_vptr_pmf_repro.cc && ./a.out
// dies with SIGSEGV (and with -fsanitize=undefined reports "object has
// invalid vptr" first); without the flag, or with clang++, it prints n=1.
// This is the shape of LCM's LCMMHUntypedSubscription::cb_func.
#include <cstdio>

struct Base {
  virtual ~Base() {}
};
struct Handler {
  int n = 0;
  void On(int x) { n += x; }
};
template <class C>
struct Subscription : Base {
  C* handler = nullptr;
  void (C::*method)(int) = nullptr;
  static void Callback(void* user_data) {
    auto* s = static_cast<Subscription*>(user_data);
    (s->handler->*s->method)(1);
  }
};

int main() {
  Handler h;
  auto* s = new Subscription<Handler>();
  s->handler = &h;
  s->method = &Handler::On;
  Subscription<Handler>::Callback(s);
  std::printf("n=%d\n", h.n);
  delete s;
}
