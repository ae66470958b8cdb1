// What the tests of the linear response and of the continuous fit share.
#pragma once
#include "engine/api/scene.h"

namespace springfit {

inline Scene WithResponse(Scene s, Response response) {
  s.search.response = response;
  return s;
}

}  // namespace springfit
